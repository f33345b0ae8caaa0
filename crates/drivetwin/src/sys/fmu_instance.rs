//! An FMU instance that can move to the thread that runs its cell.
//!
//! The `fmi` crate's instances hold the C pointer the FMU returned, so they are not `Send`.
//! FMI 3.0 (§2.2.2, "thread safety") lets an importer call an instance from any thread as long
//! as no two calls on it run at the same time, and FMI 2.0 asks no more of an importer (its
//! functions need not be thread-safe: calls on one instance never overlap). [`FmuInstance`] is
//! owned by one drive's load and every call takes `&mut self`: it is built on one thread and
//! then only moved, never shared.

use std::ops::{Deref, DerefMut};

/// A co-simulation instance (FMI 2.0 or 3.0), owned, callable from the thread that owns it.
pub struct FmuInstance<I>(I);

impl<I> FmuInstance<I> {
    pub fn new(instance: I) -> Self {
        FmuInstance(instance)
    }
}

// SAFETY: the instance is owned and reached only through `&mut self` (no `Sync`), so moving
// it to another thread never lets two calls on it overlap, which is all FMI 3.0 asks.
unsafe impl Send for FmuInstance<fmi::fmi3::instance::InstanceCS> {}

// SAFETY: as for FMI 3.0: FMI 2.0 asks only that calls on one instance never overlap.
unsafe impl Send for FmuInstance<fmi::fmi2::instance::InstanceCS> {}

impl<I> Deref for FmuInstance<I> {
    type Target = I;
    fn deref(&self) -> &I {
        &self.0
    }
}

impl<I> DerefMut for FmuInstance<I> {
    fn deref_mut(&mut self) -> &mut I {
        &mut self.0
    }
}
