//! A 16-bit word of named bits (CiA 402 controlword and statusword), built like the FHPP
//! control bytes (`vendors/festo_cmmo_st/fhpp/control_bytes.rs`): callers write `cw.contains(Controlword::HALT)`,
//! never `cw & 0x0100`.

/// The set operations every named-bit newtype has, over its integer type: `bits`,
/// `contains`, `intersects`, `with`, `when`, `union`, `difference`, `|`, `|=`, `&`.
/// Shared by [`bit_word!`] and the FHPP control and status bytes (`festo_cmmo_st::fhpp::bit_byte!`).
macro_rules! bit_set_ops {
    ($name:ident, $int:ty) => {
        impl $name {
            /// No bit set.
            pub const EMPTY: $name = $name(0);

            pub const fn bits(self) -> $int {
                self.0
            }
            /// Whether every bit of `other` is set.
            pub const fn contains(self, other: $name) -> bool {
                self.0 & other.0 == other.0
            }
            /// Whether any bit of `other` is set.
            pub const fn intersects(self, other: $name) -> bool {
                self.0 & other.0 != 0
            }
            /// `self` with the bits of `other` set (`on`) or cleared.
            #[must_use]
            pub const fn with(self, other: $name, on: bool) -> $name {
                if on {
                    $name(self.0 | other.0)
                } else {
                    $name(self.0 & !other.0)
                }
            }
            /// `self` if `on`, else no bit.
            pub const fn when(self, on: bool) -> $name {
                if on {
                    self
                } else {
                    $name(0)
                }
            }
            pub const fn union(self, other: $name) -> $name {
                $name(self.0 | other.0)
            }
            pub const fn difference(self, other: $name) -> $name {
                $name(self.0 & !other.0)
            }
        }

        impl core::ops::BitOr for $name {
            type Output = $name;
            fn bitor(self, rhs: $name) -> $name {
                $name(self.0 | rhs.0)
            }
        }

        impl core::ops::BitOrAssign for $name {
            fn bitor_assign(&mut self, rhs: $name) {
                self.0 |= rhs.0;
            }
        }

        impl core::ops::BitAnd for $name {
            type Output = $name;
            fn bitand(self, rhs: $name) -> $name {
                $name(self.0 & rhs.0)
            }
        }
    };
}

/// Declares a `u16` newtype with named bit constants and set operations.
macro_rules! bit_word {
    (
        $(#[$meta:meta])*
        $name:ident { $( $(#[$bmeta:meta])* $bit:ident = $value:expr; )* }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
        pub struct $name(pub u16);

        impl $name {
            $( $(#[$bmeta])* pub const $bit: $name = $name($value); )*
        }

        $crate::bit_word::bit_set_ops!($name, u16);
    };
}

pub(crate) use bit_set_ops;
pub(crate) use bit_word;
