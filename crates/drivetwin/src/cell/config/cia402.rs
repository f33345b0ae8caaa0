//! The keys every CiA 402 drive has (each built-in CiA 402 device and a drive from its EDS):
//! its servo motor (`[drive.motor]`), the travel of its axis (`[drive.travel]`) and how long a
//! mode change takes (`mode_change_time_ms`).

use serde::Deserialize;

use super::device_keys::Key;
use drive::drive::DriveSettings;
use drive::motor::MotorData;
use drive::travel::{HomeSwitch, TravelSettings};

/// The keys of a CiA 402 drive.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Cia402Keys {
    /// Motor and load (SI units); unset fields keep the EMMS-AS defaults.
    #[serde(default)]
    pub motor: MotorSection,
    /// Limit switches, home switch, index pulse and hard stops of the axis.
    #[serde(default)]
    pub travel: TravelSection,
    /// How long a mode change takes (6061h reads −1 meanwhile), ms.
    pub mode_change_time_ms: Option<f64>,
}

/// What each key is, for the refusal of the key on another device.
pub const KEYS: [Key; 3] = [
    Key {
        name: "motor",
        what: "servo motor of a CiA 402 drive (the CMMO-ST's stepper is [drive.stepper])",
    },
    Key {
        name: "travel",
        what: "CiA 402 axis travel in increments (the CMMO-ST's axis is [drive.axis])",
    },
    Key {
        name: "mode_change_time_ms",
        what: "CiA 402 modes of operation (6060h / 6061h)",
    },
];

/// `[drive.motor]`: overrides of [`MotorData`].
#[derive(Debug, Clone, Deserialize, Default, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MotorSection {
    pub torque_constant: Option<f64>,
    pub resistance: Option<f64>,
    pub inductance: Option<f64>,
    pub inertia: Option<f64>,
    pub viscous_friction: Option<f64>,
    pub coulomb_friction: Option<f64>,
    pub load_torque: Option<f64>,
    pub brake_holding_torque: Option<f64>,
    pub rated_current: Option<f64>,
    pub peak_current: Option<f64>,
    pub i2t_time: Option<f64>,
    pub max_speed_rpm: Option<f64>,
}

impl MotorSection {
    pub fn motor(&self) -> MotorData {
        let d = MotorData::default();
        MotorData {
            torque_constant: self.torque_constant.unwrap_or(d.torque_constant),
            resistance: self.resistance.unwrap_or(d.resistance),
            inductance: self.inductance.unwrap_or(d.inductance),
            inertia: self.inertia.unwrap_or(d.inertia),
            viscous_friction: self.viscous_friction.unwrap_or(d.viscous_friction),
            coulomb_friction: self.coulomb_friction.unwrap_or(d.coulomb_friction),
            load_torque: self.load_torque.unwrap_or(d.load_torque),
            brake_holding_torque: self.brake_holding_torque.unwrap_or(d.brake_holding_torque),
            rated_current: self.rated_current.unwrap_or(d.rated_current),
            peak_current: self.peak_current.unwrap_or(d.peak_current),
            i2t_time: self.i2t_time.unwrap_or(d.i2t_time),
            max_speed_rpm: self.max_speed_rpm.unwrap_or(d.max_speed_rpm),
            increments_per_rev: d.increments_per_rev,
        }
    }

    pub(super) fn check(&self) -> Result<(), String> {
        let positive = [
            ("torque_constant", self.torque_constant),
            ("resistance", self.resistance),
            ("inductance", self.inductance),
            ("inertia", self.inertia),
            ("rated_current", self.rated_current),
            ("peak_current", self.peak_current),
            ("i2t_time", self.i2t_time),
            ("max_speed_rpm", self.max_speed_rpm),
        ];
        for (name, v) in positive {
            if let Some(v) = v {
                if !(v.is_finite() && v > 0.0) {
                    return Err(format!("motor.{name} must be a positive number"));
                }
            }
        }
        for (name, v) in [
            ("viscous_friction", self.viscous_friction),
            ("coulomb_friction", self.coulomb_friction),
            ("brake_holding_torque", self.brake_holding_torque),
            ("load_torque", self.load_torque),
        ] {
            if let Some(v) = v {
                if !v.is_finite() || (name != "load_torque" && v < 0.0) {
                    return Err(format!("motor.{name} must be a finite number ≥ 0"));
                }
            }
        }
        Ok(())
    }
}

/// `[drive.travel]`: overrides of [`TravelSettings`], in motor encoder increments (65536 per
/// revolution; the encoder reads 0 at power-on). Unset fields keep the defaults: limit
/// switches from −20 / +64 revolutions, hard stops at −22 / +66, home cam 40000 … 90000, index
/// at 16384 (see [`TravelSettings::default`]).
#[derive(Debug, Clone, Deserialize, Default, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TravelSection {
    pub negative_stop: Option<i64>,
    pub negative_limit: Option<i64>,
    pub home_switch_low: Option<i64>,
    pub home_switch_high: Option<i64>,
    pub positive_limit: Option<i64>,
    pub positive_stop: Option<i64>,
    pub index_phase: Option<u32>,
    /// Longest homing search step, increments (0: no limit; beyond it error 11-6).
    pub homing_max_distance: Option<i64>,
}

/// Positions beyond ±2^40 increments (16 million revolutions) are refused: far from any
/// axis, and safe from overflow in the position arithmetic.
const TRAVEL_LIMIT: i64 = 1 << 40;

impl TravelSection {
    /// The travel and the homing search limit, or what is wrong with them.
    pub fn travel(&self) -> Result<(TravelSettings, i64), String> {
        let d = TravelSettings::default();
        let pick = |v: Option<i64>, dflt: Option<i64>| v.or(dflt);
        let home = d.home_switch.map(|h| HomeSwitch {
            low: self.home_switch_low.unwrap_or(h.low),
            high: self.home_switch_high.unwrap_or(h.high),
        });
        let t = TravelSettings {
            negative_stop: pick(self.negative_stop, d.negative_stop),
            negative_limit: pick(self.negative_limit, d.negative_limit),
            home_switch: home,
            positive_limit: pick(self.positive_limit, d.positive_limit),
            positive_stop: pick(self.positive_stop, d.positive_stop),
            index_phase: self.index_phase.or(d.index_phase),
        };
        let order = [
            ("negative_stop", t.negative_stop),
            ("negative_limit", t.negative_limit),
            ("positive_limit", t.positive_limit),
            ("positive_stop", t.positive_stop),
        ];
        for (name, v) in order.iter().chain(
            [
                ("home_switch_low", home.map(|h| h.low)),
                ("home_switch_high", home.map(|h| h.high)),
            ]
            .iter(),
        ) {
            if v.is_some_and(|v| v.abs() > TRAVEL_LIMIT) {
                return Err(format!("travel.{name} must lie within ±2^40 increments"));
            }
        }
        for w in order.windows(2) {
            if let [(a, Some(x)), (b, Some(y))] = w {
                if x >= y {
                    return Err(format!("travel.{a} must lie below travel.{b}"));
                }
            }
        }
        if home.is_some_and(|h| h.low > h.high) {
            return Err("travel.home_switch_low must not lie above home_switch_high".into());
        }
        if t.index_phase
            .is_some_and(|p| p >= drive::motor::INCREMENTS_PER_REV)
        {
            return Err("travel.index_phase must lie within one revolution (0 … 65535)".into());
        }
        let max = self
            .homing_max_distance
            .unwrap_or(DriveSettings::default().homing_max_distance);
        if !(0..=TRAVEL_LIMIT).contains(&max) {
            return Err("travel.homing_max_distance must lie within 0 … 2^40".into());
        }
        Ok((t, max))
    }
}
