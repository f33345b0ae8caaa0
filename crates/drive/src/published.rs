//! Actual values a cycle publishes into the object dictionary, remembered so that a store of
//! the value an entry already holds is skipped.
//!
//! Most published values stand for many cycles (the statusword, the error words, the inputs,
//! a current of 0 at rest). A pass of stores (one cycle's `publish`) is bracketed by
//! [`Published::begin`] and [`Published::end`]: if the dictionary took any store between the
//! end of one pass and the start of the next ([`od::ObjectDictionary::stores`] — a master's
//! write, a console, a restore, another cycle's logic), every remembered value is forgotten
//! and the pass stores all of them. Within a pass each site has its own slot and is the only
//! writer of its entry, so a slot's value is what its entry holds.

/// The values of up to `N` (≤ 64) publishing sites, slot by slot, of type `T` (an integer, or
/// anything whose equality means "the same bytes").
#[derive(Debug, Clone, Copy)]
pub struct Published<T, const N: usize> {
    values: [T; N],
    /// The slots whose value in `values` is the one last stored (bit n: slot n).
    known: u64,
    /// The dictionary's store count at the end of the last pass.
    stores: u64,
    /// The dictionary took no store between the last pass and this one.
    intact: bool,
    /// The slots stored in this pass: each site is its entry's one writer in a pass.
    #[cfg(debug_assertions)]
    seen: u64,
}

impl<T: Copy + Default, const N: usize> Default for Published<T, N> {
    fn default() -> Self {
        const { assert!(N <= 64, "a u64 tracks the slots") };
        Published {
            values: [T::default(); N],
            known: 0,
            stores: 0,
            intact: false,
            #[cfg(debug_assertions)]
            seen: 0,
        }
    }
}

impl<T: Copy + PartialEq, const N: usize> Published<T, N> {
    /// A pass starts, the dictionary at store count `stores`: a store since the last pass
    /// ended forgets every value. Returns whether the dictionary is as the last pass left it.
    #[inline]
    pub fn begin(&mut self, stores: u64) -> bool {
        let intact = stores == self.stores;
        if !intact {
            self.known = 0;
        }
        self.intact = intact;
        #[cfg(debug_assertions)]
        {
            self.seen = 0;
        }
        intact
    }

    /// What [`Published::begin`] found for this pass: the dictionary as the last pass left it
    /// (what a pass derived from it then still holds).
    #[inline]
    pub fn intact(&self) -> bool {
        self.intact
    }

    /// The pass ends, the dictionary at store count `stores` (its own stores included).
    #[inline]
    pub fn end(&mut self, stores: u64) {
        self.stores = stores;
    }

    /// Whether slot `n`'s entry already holds `v` (skip the store); otherwise `v` is
    /// remembered as slot `n`'s, to be stored now.
    #[inline(always)]
    pub fn unchanged(&mut self, n: usize, v: T) -> bool {
        let bit = 1u64.checked_shl(n as u32).unwrap_or(0);
        #[cfg(debug_assertions)]
        {
            debug_assert!(
                self.seen & bit == 0,
                "publishing slot {n} used twice in a pass"
            );
            self.seen |= bit;
        }
        let Some(last) = self.values.get_mut(n) else {
            return false;
        };
        if self.known & bit != 0 && *last == v {
            return true;
        }
        *last = v;
        self.known |= bit;
        false
    }

    /// Slot `n`'s value is not known (its store was not made, or not of a value compared
    /// by `==`): the next pass stores it.
    #[inline(always)]
    pub fn unknown(&mut self, n: usize) {
        self.known &= !1u64.checked_shl(n as u32).unwrap_or(0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_value_is_skipped_until_the_dictionary_is_written_between_passes() {
        let mut p = Published::<i64, 4>::default();
        assert!(!p.intact(), "no pass before the first");
        assert!(p.begin(0));
        assert!(p.intact());
        assert!(!p.unchanged(1, 5), "the first store is made");
        p.end(1);
        assert!(p.begin(1));
        assert!(p.unchanged(1, 5), "the same value again is skipped");
        p.end(1);
        assert!(p.begin(1));
        assert!(!p.unchanged(1, 6), "another value is stored");
        assert!(!p.unchanged(2, 6), "another slot is its own");
        p.end(3);
        // A store between the passes (count 3 → 4): everything is stored again.
        assert!(!p.begin(4));
        assert!(!p.intact());
        assert!(!p.unchanged(1, 6));
        assert!(!p.unchanged(2, 6));
        p.end(6);
        assert!(p.begin(6));
        p.unknown(2);
        assert!(p.unchanged(1, 6));
        assert!(!p.unchanged(2, 6));
        // A slot beyond N is never skipped.
        assert!(!p.unchanged(9, 6));
        p.end(6);
        assert!(p.begin(6));
        assert!(!p.unchanged(9, 6));
    }

    #[test]
    #[cfg(debug_assertions)]
    #[should_panic(expected = "used twice")]
    fn a_slot_stored_twice_in_a_pass_is_a_bug() {
        let mut p = Published::<i64, 4>::default();
        p.begin(0);
        p.unchanged(1, 5);
        p.unchanged(1, 6);
    }
}
