//! SDO abort codes (CiA 301 §7.2.4.3.17), used by every front end that reaches the dictionary.

/// An SDO abort code. A newtype rather than an enum, because a master must also carry codes
/// a real device sends that the standard does not list.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct AbortCode(pub u32);

macro_rules! abort_codes {
    ($($name:ident = $code:literal, $text:literal;)*) => {
        impl AbortCode {
            $(pub const $name: AbortCode = AbortCode($code);)*

            /// The text of the CiA 301 table, or `None` for a code it does not list.
            pub const fn description(self) -> Option<&'static str> {
                match self.0 {
                    $($code => Some($text),)*
                    _ => None,
                }
            }
        }
    };
}

abort_codes! {
    TOGGLE_BIT = 0x0503_0000, "Toggle bit not alternated";
    TIMEOUT = 0x0504_0000, "SDO protocol timed out";
    COMMAND_SPECIFIER = 0x0504_0001, "Client/server command specifier not valid or unknown";
    BLOCK_SIZE = 0x0504_0002, "Invalid block size (block mode only)";
    SEQUENCE_NUMBER = 0x0504_0003, "Invalid sequence number (block mode only)";
    CRC = 0x0504_0004, "CRC error (block mode only)";
    OUT_OF_MEMORY = 0x0504_0005, "Out of memory";
    UNSUPPORTED_ACCESS = 0x0601_0000, "Unsupported access to an object";
    WRITE_ONLY = 0x0601_0001, "Attempt to read a write only object";
    READ_ONLY = 0x0601_0002, "Attempt to write a read only object";
    NO_OBJECT = 0x0602_0000, "Object does not exist in the object dictionary";
    NOT_MAPPABLE = 0x0604_0041, "Object cannot be mapped to the PDO";
    PDO_LENGTH = 0x0604_0042, "The number and length of the objects to be mapped would exceed PDO length";
    PARAMETER_INCOMPATIBLE = 0x0604_0043, "General parameter incompatibility reason";
    INTERNAL_INCOMPATIBLE = 0x0604_0047, "General internal incompatibility in the device";
    HARDWARE = 0x0606_0000, "Access failed due to a hardware error";
    LENGTH_MISMATCH = 0x0607_0010, "Data type does not match, length of service parameter does not match";
    LENGTH_TOO_HIGH = 0x0607_0012, "Data type does not match, length of service parameter too high";
    LENGTH_TOO_LOW = 0x0607_0013, "Data type does not match, length of service parameter too low";
    NO_SUB_INDEX = 0x0609_0011, "Sub-index does not exist";
    INVALID_VALUE = 0x0609_0030, "Invalid value for parameter (download only)";
    VALUE_TOO_HIGH = 0x0609_0031, "Value of parameter written too high (download only)";
    VALUE_TOO_LOW = 0x0609_0032, "Value of parameter written too low (download only)";
    MAX_LESS_THAN_MIN = 0x0609_0036, "Maximum value is less than minimum value";
    NO_RESOURCE = 0x060A_0023, "Resource not available: SDO connection";
    GENERAL = 0x0800_0000, "General error";
    CANNOT_STORE = 0x0800_0020, "Data cannot be transferred or stored to the application";
    LOCAL_CONTROL = 0x0800_0021, "Data cannot be transferred or stored to the application because of local control";
    DEVICE_STATE = 0x0800_0022, "Data cannot be transferred or stored to the application because of the present device state";
    NO_DICTIONARY = 0x0800_0023, "Object dictionary dynamic generation fails or no object dictionary is present";
    NO_DATA = 0x0800_0024, "No data available";
}

impl core::fmt::Display for AbortCode {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.description() {
            Some(text) => write!(f, "0x{:08X} ({})", self.0, text),
            None => write!(f, "0x{:08X} (unknown abort code)", self.0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_and_unknown_codes_describe_themselves() {
        assert_eq!(
            AbortCode::READ_ONLY.description(),
            Some("Attempt to write a read only object")
        );
        assert_eq!(AbortCode(0x1234_5678).description(), None);
    }
}
