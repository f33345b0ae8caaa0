//! Lists of object keys `(index, sub)` merged when compiling: the objects a drive caches are
//! CiA 402's list and its vendor's
//! ([`Vendor`](crate::personality::Vendor)'s `CACHED_OBJECTS`) as one sorted set.

/// `(index, sub)` as one ordered key.
const fn key(k: (u16, u8)) -> u32 {
    (k.0 as u32) << 8 | k.1 as u32
}

/// The smallest key of `base` and `lists` above `after` (`None`: the smallest of all).
// Evaluated when compiling: `i` and `j` stay below the lengths they are checked against.
#[allow(clippy::indexing_slicing)]
const fn next_above(
    base: &[(u16, u8)],
    lists: &[&[(u16, u8)]],
    after: Option<u32>,
) -> Option<(u16, u8)> {
    let mut best: Option<(u16, u8)> = None;
    let mut i = 0;
    while i <= lists.len() {
        let list = if i == 0 { base } else { lists[i - 1] };
        let mut j = 0;
        while j < list.len() {
            let k = key(list[j]);
            let above = match after {
                Some(a) => k > a,
                None => true,
            };
            let smaller = match best {
                Some(b) => k < key(b),
                None => true,
            };
            if above && smaller {
                best = Some(list[j]);
            }
            j += 1;
        }
        i += 1;
    }
    best
}

/// How many distinct keys `base` and `lists` hold together.
pub(crate) const fn merged_len(base: &[(u16, u8)], lists: &[&[(u16, u8)]]) -> usize {
    let mut n = 0;
    let mut last = None;
    while let Some(k) = next_above(base, lists, last) {
        n += 1;
        last = Some(key(k));
    }
    n
}

/// The keys of `base` and `lists` sorted by (index, sub), each once, in the first
/// [`merged_len`] of `N` places; the rest `(0, 0)`.
// Evaluated when compiling: `n` stays below N (asserted).
#[allow(clippy::indexing_slicing)]
pub(crate) const fn merged<const N: usize>(
    base: &[(u16, u8)],
    lists: &[&[(u16, u8)]],
) -> [(u16, u8); N] {
    let mut out = [(0u16, 0u8); N];
    let mut n = 0;
    let mut last = None;
    while let Some(k) = next_above(base, lists, last) {
        assert!(n < N, "more keys than places");
        out[n] = k;
        n += 1;
        last = Some(key(k));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merges_sorted_without_duplicates() {
        const A: &[(u16, u8)] = &[(0x6081, 0), (0x60F9, 3)];
        const B: &[(u16, u8)] = &[(0x60F9, 1), (0x6081, 0), (0x60F9, 0x10)];
        const N: usize = merged_len(A, &[B]);
        const M: [(u16, u8); 5] = merged(A, &[B]);
        assert_eq!(N, 4);
        assert_eq!(
            M,
            [
                (0x6081, 0),
                (0x60F9, 1),
                (0x60F9, 3),
                (0x60F9, 0x10),
                (0, 0)
            ]
        );
    }
}
