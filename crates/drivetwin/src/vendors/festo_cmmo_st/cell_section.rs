//! The CMMO-ST's keys of a `[[drive]]` (its section of the cell file,
//! [`crate::cell::config::DeviceSection`]): its Modbus TCP server (`modbus`,
//! `modbus_timeout_ms`), its stepper motor (`[drive.stepper]`) and its axis (`[drive.axis]`).

use serde::Deserialize;

use crate::cell::config::{DeviceSection, DriveContext, FhppSpec, Key, OwnSettings, SectionError};
use drive::stepper::{StepperData, StepperMode};
use drive::vendors::festo_cmmo_st::axis_mechanics::AxisMechanics;
use drive::vendors::festo_cmmo_st::device::FhppSettings;

/// The CMMO-ST's section.
pub const SECTION: DeviceSection = DeviceSection {
    devices: &["cmmo-st"],
    keys: &KEYS,
    read,
};

/// The keys only a CMMO-ST has.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CmmoStKeys {
    /// Its Modbus TCP server address (default 127.0.0.1:1502; every CMMO-ST of a cell needs
    /// its own).
    pub modbus: Option<String>,
    /// Its Modbus connection watchdog, ms (0 = off, the factory setting).
    pub modbus_timeout_ms: Option<u16>,
    /// Its stepper motor, load and control mode.
    #[serde(default)]
    pub stepper: StepperSection,
    /// Its axis: end stops, reference switch, index pulse (homing).
    #[serde(default)]
    pub axis: AxisSection,
}

/// What each key is, for the refusal of the key on another device.
pub const KEYS: [Key; 4] = [
    Key {
        name: "modbus",
        what: "Modbus TCP server (the CMMO-ST's fieldbus)",
    },
    Key {
        name: "modbus_timeout_ms",
        what: "Modbus connection watchdog (the CMMO-ST's)",
    },
    Key {
        name: "stepper",
        what: "stepper motor section (the CMMO-ST's [drive.stepper])",
    },
    Key {
        name: "axis",
        what: "axis section in revolutions (the CMMO-ST's [drive.axis])",
    },
];

/// Reads a CMMO-ST's keys: how it is simulated (stepper, axis) and served (Modbus TCP).
fn read(table: toml::Table, _: &DriveContext<'_>) -> Result<OwnSettings, SectionError> {
    let k = CmmoStKeys::deserialize(toml::Value::Table(table))?;
    let (stepper, mode) = k.stepper.stepper().map_err(SectionError::key("stepper"))?;
    let mechanics = k.axis.mechanics().map_err(SectionError::key("axis"))?;
    Ok(OwnSettings {
        fhpp: Some(FhppSpec {
            settings: FhppSettings {
                stepper,
                mode,
                mechanics,
                ..FhppSettings::default()
            },
            modbus: k.modbus,
            watchdog_ms: k.modbus_timeout_ms,
        }),
        ..OwnSettings::default()
    })
}

/// `[drive.stepper]`: the CMMO-ST's motor and load; unset fields keep the defaults of
/// [`StepperData`] (an EMMS-ST-42-class motor with a light load, closed loop).
#[derive(Debug, Clone, Deserialize, Default, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct StepperSection {
    /// `"closed-loop"` (the CMMO-ST with its encoder) or `"open-loop"` (steps are lost when
    /// the load exceeds the pull-out torque).
    pub mode: Option<StepperModeName>,
    pub holding_torque: Option<f64>,
    pub load_inertia: Option<f64>,
    pub load_torque: Option<f64>,
    pub coulomb_friction: Option<f64>,
    pub viscous_friction: Option<f64>,
    pub supply_voltage: Option<f64>,
}

/// `mode` of `[drive.stepper]`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum StepperModeName {
    ClosedLoop,
    OpenLoop,
}

impl StepperSection {
    /// The stepper data and mode, or what is wrong with them.
    pub fn stepper(&self) -> Result<(StepperData, StepperMode), String> {
        let d = StepperData::default();
        for (name, v, positive) in [
            ("holding_torque", self.holding_torque, true),
            ("supply_voltage", self.supply_voltage, true),
            ("load_inertia", self.load_inertia, false),
            ("coulomb_friction", self.coulomb_friction, false),
            ("viscous_friction", self.viscous_friction, false),
        ] {
            if let Some(v) = v {
                if !(v.is_finite() && (v > 0.0 || (!positive && v == 0.0))) {
                    let bound = if positive { "> 0" } else { "≥ 0" };
                    return Err(format!("stepper.{name} must be a number {bound}"));
                }
            }
        }
        if self.load_torque.is_some_and(|v| !v.is_finite()) {
            return Err("stepper.load_torque must be a finite number".into());
        }
        let data = StepperData {
            holding_torque: self.holding_torque.unwrap_or(d.holding_torque),
            load_inertia: self.load_inertia.unwrap_or(d.load_inertia),
            load_torque: self.load_torque.unwrap_or(d.load_torque),
            coulomb_friction: self.coulomb_friction.unwrap_or(d.coulomb_friction),
            viscous_friction: self.viscous_friction.unwrap_or(d.viscous_friction),
            supply_voltage: self.supply_voltage.unwrap_or(d.supply_voltage),
            ..d
        };
        let mode = match self.mode {
            Some(StepperModeName::OpenLoop) => StepperMode::OpenLoop,
            Some(StepperModeName::ClosedLoop) | None => StepperMode::ClosedLoop,
        };
        Ok((data, mode))
    }
}

/// Something fitted to the axis at a place, or `"none"`.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum Fitted<T> {
    At(T),
    Absent(String),
}

impl<T: Copy> Fitted<T> {
    fn get(&self, name: &str) -> Result<Option<T>, String> {
        match self {
            Fitted::At(v) => Ok(Some(*v)),
            Fitted::Absent(s) if s == "none" => Ok(None),
            Fitted::Absent(s) => Err(format!(
                "axis.{name}: {s:?} is neither a place nor \"none\""
            )),
        }
    }
}

/// `[drive.axis]`: the CMMO-ST's axis in motor revolutions from the power-on position; unset
/// fields keep [`AxisMechanics::default`] (stops at −3 / +47, a reference cam −0.05 … 0.05,
/// index pulse at 0.3 of each revolution). `"none"` removes a part (an endless axis, no
/// switch, an encoder without index).
#[derive(Debug, Clone, Deserialize, Default, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AxisSection {
    pub end_stops: Option<Fitted<[f64; 2]>>,
    pub reference_switch: Option<Fitted<[f64; 2]>>,
    pub index_pulse: Option<Fitted<f64>>,
}

impl AxisSection {
    /// The axis, or what is wrong with it.
    pub fn mechanics(&self) -> Result<AxisMechanics, String> {
        let d = AxisMechanics::default();
        let pair = |name: &str, v: &Option<Fitted<[f64; 2]>>, dflt: Option<(f64, f64)>| {
            let Some(v) = v else {
                return Ok(dflt);
            };
            match v.get(name)? {
                None => Ok(None),
                Some([lo, hi]) if lo.is_finite() && hi.is_finite() && lo <= hi => {
                    Ok(Some((lo, hi)))
                }
                Some(_) => Err(format!("axis.{name} must be [low, high] with low ≤ high")),
            }
        };
        let end_stops = pair("end_stops", &self.end_stops, d.end_stops)?;
        if end_stops.is_some_and(|(lo, hi)| lo == hi || lo.abs().max(hi.abs()) > 1e6) {
            return Err("axis.end_stops must lie apart, within ±10^6 revolutions".into());
        }
        let reference_switch = pair(
            "reference_switch",
            &self.reference_switch,
            d.reference_switch,
        )?;
        let index_pulse = match &self.index_pulse {
            None => d.index_pulse,
            Some(v) => match v.get("index_pulse")? {
                Some(f) if (0.0..1.0).contains(&f) => Some(f),
                Some(_) => {
                    return Err(
                        "axis.index_pulse must lie in 0 … 1 (a fraction of a revolution)".into(),
                    )
                }
                None => None,
            },
        };
        Ok(AxisMechanics {
            end_stops,
            reference_switch,
            index_pulse,
        })
    }
}
