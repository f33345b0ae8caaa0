//! The file format, as serde reads it. Checked and normalised in `model`.

use serde::Deserialize;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct File {
    pub device: DeviceSection,
    #[serde(default)]
    pub object: Vec<ObjectSection>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeviceSection {
    pub name: String,
    pub product_name: String,
    pub vendor_name: String,
    pub vendor_id: u32,
    #[serde(default)]
    pub product_code: u32,
    #[serde(default)]
    pub revision: u32,
    #[serde(default)]
    pub order_code: String,
    #[serde(default)]
    pub description: String,
    /// `cia402`, `fhpp` or `plain`: how the twin builds and serves the personality.
    pub profile: ProfileName,
    #[serde(default = "default_node")]
    pub default_node_id: u8,
    #[serde(default)]
    pub baud_rates: Vec<u16>,
    #[serde(default)]
    pub pdo_params_locked_while_valid: bool,
    #[serde(default)]
    pub pdo_config_outside_operational: bool,
    pub tpdo_transmit_mask_index: Option<u16>,
    #[serde(default)]
    pub tpdo_254_cyclic_inhibit: bool,
}

/// `profile` of `[device]`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum ProfileName {
    Cia402,
    Fhpp,
    Plain,
}

fn default_node() -> u8 {
    1
}

/// Fields shared by a VAR object and a sub-entry.
#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct EntryFields {
    #[serde(rename = "type")]
    pub data_type: Option<String>,
    pub access: Option<String>,
    pub pdo: Option<bool>,
    pub default: Option<toml::Value>,
    pub min: Option<toml::Value>,
    pub max: Option<toml::Value>,
    pub unit: Option<String>,
    pub size: Option<u32>,
    pub behaviour: Option<String>,
    pub storable: Option<bool>,
    pub source: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectSection {
    pub index: u16,
    pub name: String,
    pub kind: Option<String>,
    #[serde(rename = "type")]
    pub data_type: Option<String>,
    pub access: Option<String>,
    pub pdo: Option<bool>,
    pub default: Option<toml::Value>,
    pub min: Option<toml::Value>,
    pub max: Option<toml::Value>,
    pub unit: Option<String>,
    pub size: Option<u32>,
    pub behaviour: Option<String>,
    pub storable: Option<bool>,
    pub source: Option<String>,
    #[serde(default)]
    pub sub: Vec<SubSection>,
}

/// A sub-entry of an ARRAY or RECORD: the fields of [`EntryFields`] plus its sub-index.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SubSection {
    pub sub: u8,
    pub name: String,
    #[serde(rename = "type")]
    pub data_type: Option<String>,
    pub access: Option<String>,
    pub pdo: Option<bool>,
    pub default: Option<toml::Value>,
    pub min: Option<toml::Value>,
    pub max: Option<toml::Value>,
    pub unit: Option<String>,
    pub size: Option<u32>,
    pub behaviour: Option<String>,
    pub storable: Option<bool>,
    pub source: Option<String>,
}

impl SubSection {
    pub fn fields(&self) -> EntryFields {
        EntryFields {
            data_type: self.data_type.clone(),
            access: self.access.clone(),
            pdo: self.pdo,
            default: self.default.clone(),
            min: self.min.clone(),
            max: self.max.clone(),
            unit: self.unit.clone(),
            size: self.size,
            behaviour: self.behaviour.clone(),
            storable: self.storable,
            source: self.source.clone(),
        }
    }
}

impl ObjectSection {
    /// The VAR fields of this object, as an entry.
    pub fn var_fields(&self) -> EntryFields {
        EntryFields {
            data_type: self.data_type.clone(),
            access: self.access.clone(),
            pdo: self.pdo,
            default: self.default.clone(),
            min: self.min.clone(),
            max: self.max.clone(),
            unit: self.unit.clone(),
            size: self.size,
            behaviour: self.behaviour.clone(),
            storable: self.storable,
            source: self.source.clone(),
        }
    }
}
