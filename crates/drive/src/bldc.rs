//! A brushless DC motor with Hall sensors behind a Nanotec (Nanotec §1.2 and §11.5:
//! 2004h:07 "Motortyp", 2004h:0C "Hall-Sensor-Modus"): the servo [`crate::axis::Axis`] (its PMSM
//! and its current / velocity / position cascade) with block (six-step) commutation from the Hall
//! sectors.
//!
//! Model: the rotor's electrical angle `θe = pole pairs × θ` lies in one of six 60° sectors
//! `k = ⌊θe / 60°⌋`; the motor's Hall sequence (its data sheet) gives the Hall state of sector
//! `k`, its index `H1 + 2·H2 + 4·H3`. The drive maps that index through 2004h:0C to one of its
//! six commutation vectors and energises it; the torque is `Kt · i · sin(θ_vector − θe)`.
//!
//! Decisions (the manual gives the table, not the firmware's reading of it):
//! * The six hex digits of 2004h:0C, the highest first, are the vectors for the Hall indices
//!   4, 6, 2, 3, 1, 5: the Hall order of the Nanotec motors (the DB57 example). Read so, the
//!   digit for index `i` of the default 243015h is exactly the type-1 table's value for `i`,
//!   and of 510342h the type-2 (DB42) value: the manual's table is the drive's lookup.
//! * Vector `v` points to `60° × n + 120°` electrical, `n` its place in 2, 4, 3, 0, 1, 5 (the
//!   DB57 example's values): with 243015h a DB57 gets each sector's vector 90° ahead of the
//!   sector's middle, the block commutation that turns it.
//! * A wrong table (510342h on a DB57) energises vectors that pull backwards in two of the six
//!   sectors (sin < 0) and 60° off in the others: the rotor runs into the boundary between a
//!   forward and a backward sector and stays there, the position controller saturates —
//!   the motor stalls (it jerks to that boundary, then hums), as a real BLDC with a wrong
//!   sector table does. A digit above 5 energises nothing in its sector.

use core::f64::consts::{FRAC_PI_3, TAU};

/// The Hall indices the digits of 2004h:0C stand for, the highest digit first.
const DIGIT_ORDER: [u8; 6] = [4, 6, 2, 3, 1, 5];
/// The commutation vectors in electrical order (see the module doc).
const VECTOR_ORDER: [u8; 6] = [2, 4, 3, 0, 1, 5];

/// The DB57 Hall sequence of the manual's example (H1, H2, H3 per 60° electrical).
pub const DB57_HALL_SEQUENCE: [(u8, u8, u8); 6] = [
    (0, 0, 1),
    (0, 1, 1),
    (0, 1, 0),
    (1, 1, 0),
    (1, 0, 0),
    (1, 0, 1),
];

/// A Hall sequence that needs 510342h (the type-2 table of the DB42 motors): the DB57
/// sequence the other way round. Decision: the manual prints no DB42 sequence; this is the
/// one the type-2 table turns.
pub const DB42_HALL_SEQUENCE: [(u8, u8, u8); 6] = [
    (1, 0, 1),
    (1, 0, 0),
    (1, 1, 0),
    (0, 1, 0),
    (0, 1, 1),
    (0, 0, 1),
];

/// The BLDC motor's own data (its electrical and mechanical data are the servo
/// [`crate::motor::MotorData`] of the drive settings).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BldcData {
    /// Pole pairs. Default 4: a DB57-like motor (8 poles; assumed, not from the manual).
    pub pole_pairs: u32,
    /// The Hall states (H1, H2, H3) of the six 60° electrical sectors, from 0° on. Default the
    /// DB57 sequence of the manual's 2004h:0C example.
    pub hall_sequence: [(u8, u8, u8); 6],
}

impl Default for BldcData {
    fn default() -> Self {
        BldcData {
            pole_pairs: 4,
            hall_sequence: DB57_HALL_SEQUENCE,
        }
    }
}

impl BldcData {
    /// Hall edges per revolution: the position resolution with Hall sensors only.
    pub fn hall_edges_per_rev(&self) -> u32 {
        6 * self.pole_pairs.max(1)
    }

    /// The 60° sector of shaft angle `angle` (rad): 0 … 5.
    pub fn sector(&self, angle: f64) -> usize {
        let e = angle * f64::from(self.pole_pairs.max(1));
        let e = e - TAU * libm::floor(e / TAU);
        (libm::floor(e / FRAC_PI_3) as usize).min(5)
    }

    /// The Hall index `H1 + 2·H2 + 4·H3` at shaft angle `angle`.
    pub fn hall_index(&self, angle: f64) -> u8 {
        let (h1, h2, h3) = self
            .hall_sequence
            .get(self.sector(angle))
            .copied()
            .unwrap_or_default();
        (h1 & 1) + 2 * (h2 & 1) + 4 * (h3 & 1)
    }

    /// The torque factor of block commutation with 2004h:0C = `mode` at shaft angle `angle`
    /// (rad): `sin(θ_vector − θe)`, 0 where the table energises no vector.
    pub fn torque_factor(&self, mode: u32, angle: f64) -> f64 {
        let Some(v) = commutation_vector(mode, self.hall_index(angle)) else {
            return 0.0;
        };
        let Some(n) = VECTOR_ORDER.iter().position(|x| *x == v) else {
            return 0.0;
        };
        let e = angle * f64::from(self.pole_pairs.max(1));
        libm::sin(n as f64 * FRAC_PI_3 + 2.0 * FRAC_PI_3 - e)
    }
}

/// The commutation vector 2004h:0C = `mode` assigns to Hall index `index` (1 … 6); `None`
/// for index 0 or 7 or a digit above 5.
pub fn commutation_vector(mode: u32, index: u8) -> Option<u8> {
    let place = DIGIT_ORDER.iter().position(|i| *i == index)?;
    let digit = (mode >> (4 * (5 - place))) & 0xF;
    (digit <= 5).then_some(digit as u8)
}
