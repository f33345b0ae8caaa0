//! An FMU instance that can move to the thread that runs its cell.
//!
//! The `fmi` crate's instance holds the C pointer the FMU returned, so it is not `Send`. FMI
//! 3.0 (§2.2.2, "thread safety") lets an importer call an instance from any thread as long as
//! no two calls on it run at the same time. [`FmuInstance`] is owned by one drive's load and
//! every call takes `&mut self`: it is built on one thread and then only moved, never shared.

use std::ops::{Deref, DerefMut};

use fmi::fmi3::instance::InstanceCS;

/// A co-simulation instance, owned, callable from the thread that owns it.
pub struct FmuInstance(InstanceCS);

impl FmuInstance {
    pub fn new(instance: InstanceCS) -> Self {
        FmuInstance(instance)
    }
}

// SAFETY: the instance is owned and reached only through `&mut self` (no `Sync`), so moving
// it to another thread never lets two calls on it overlap, which is all FMI 3.0 asks.
unsafe impl Send for FmuInstance {}

impl Deref for FmuInstance {
    type Target = InstanceCS;
    fn deref(&self) -> &InstanceCS {
        &self.0
    }
}

impl DerefMut for FmuInstance {
    fn deref_mut(&mut self) -> &mut InstanceCS {
        &mut self.0
    }
}
