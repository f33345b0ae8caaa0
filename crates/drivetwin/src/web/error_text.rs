//! Texts of the errors the console shows: CiA 301 / CiA 402 error codes (1003h, 603Fh, EMCY)
//! with the number the drive's own diagnostic table gives the code, and the CMMO-ST's diagnostic
//! numbers with the names of its App. D.

use super::motion::ErrorView;

/// Error codes with their meaning: CiA 301 §7.2.7.1 Tab. 21 (the classes) and the drive
/// codes of CiA 402-2 (IEC 61800-7-201) Annex, the ones the twin's drives raise. A code not
/// listed takes the text of its class (the longest listed prefix).
const CODES: &[(u16, &str)] = &[
    (0x0000, "no error"),
    (0x1000, "generic error"),
    (0x2000, "current"),
    (0x2300, "current, device output side"),
    (0x2310, "continuous over-current"),
    (0x2312, "over-current (I²t)"),
    (0x3000, "voltage"),
    (0x3100, "mains voltage"),
    (0x3200, "voltage inside the device"),
    (0x3210, "DC link over-voltage"),
    (0x3220, "DC link under-voltage"),
    (0x4000, "temperature"),
    (0x4200, "device temperature"),
    (0x4310, "drive temperature too high"),
    (0x5000, "device hardware"),
    (0x5100, "supply"),
    (0x5114, "supply: logic voltage too low"),
    (0x5115, "supply: driver supply voltage"),
    (0x6000, "device software"),
    (0x6100, "internal software"),
    (0x6180, "internal software: stack overflow"),
    (0x6300, "data set"),
    (0x7000, "additional modules"),
    (0x7300, "sensor"),
    (0x7382, "sensor: encoder / resolver fault"),
    (0x8000, "monitoring"),
    (0x8081, "limit switch: negative set-point blocked"),
    (0x8082, "limit switch: positive set-point blocked"),
    (0x8083, "limit switches: both directions blocked"),
    (0x8100, "communication"),
    (0x8110, "CAN overrun (objects lost)"),
    (0x8120, "CAN in error passive mode"),
    (0x8130, "life guard or heartbeat error"),
    (0x8140, "recovered from bus off"),
    (0x8200, "protocol error"),
    (0x8210, "PDO not processed: length error"),
    (0x8220, "PDO length exceeded"),
    (0x8250, "RPDO timeout"),
    (0x8600, "positioning controller"),
    (0x8611, "following error"),
    (0x8612, "reference limit"),
    (0x8700, "sync controller"),
    (0x8780, "SYNC missing"),
    (0x8781, "SYNC interval wrong"),
    (0x8A00, "position controller"),
    (0x8A80, "homing: error at start"),
    (0x8A81, "homing: aborted"),
    (0x8A82, "homing: no index pulse"),
    (0x8A83, "homing: time-out"),
    (0x8A84, "homing: limit switch reached"),
    (0x8A85, "homing: travel too long"),
    (0x8A86, "homing: encoder fault"),
    (0x9000, "external error"),
    (0xF000, "additional functions"),
    (0xFF00, "device specific"),
];

/// The text of a CiA 301 error code: the code's own where listed, else its class's.
pub fn cia_text(code: u16) -> &'static str {
    // Exact, then the class by two hex digits, then by one (Tab. 21 groups by the high digits).
    [0xFFFF, 0xFFF0, 0xFF00, 0xF000]
        .iter()
        .find_map(|mask| {
            CODES
                .iter()
                .find(|(c, _)| *c == code & mask)
                .map(|(_, t)| *t)
        })
        .unwrap_or("unknown error code")
}

/// An error code as the console shows it: the text and number the drive's manual gives the
/// first message of its diagnostic table `table` with that code (the CMMP-AS's App. B.2
/// "43-1", the Nanotec's "0800h", the Kinco's "ES.5"); CiA 301's text for a code the table
/// does not have, or a message the manual gives no text.
pub fn cia_error(table: &[od::Diagnostic], code: u16) -> ErrorView {
    let text = match table.iter().find(|d| d.code == Some(code)) {
        Some(d) if !d.text.is_empty() => format!("{} (message {})", d.text, d.number),
        Some(d) => format!("{} (message {})", cia_text(code), d.number),
        None => cia_text(code).to_owned(),
    };
    ErrorView {
        code: format!("{code:04X}h"),
        text,
        event: None,
        time_ms: None,
    }
}

/// An FHPP diagnostic number with its name in the drive's diagnostic table `table` (the
/// CMMO-ST's App. D, whose numbers are printed "4Dh").
pub fn fhpp_diagnostic(table: &[od::Diagnostic], number: u16) -> ErrorView {
    let printed = format!("{number:02X}h");
    let text = table
        .iter()
        .find(|d| d.number.eq_ignore_ascii_case(&printed))
        .map_or("unknown diagnostic number", |d| d.text)
        .to_owned();
    ErrorView {
        code: format!("{number:02X}h"),
        text,
        event: None,
        time_ms: None,
    }
}

/// PNU 200 event types (CMMO-ST §7.3.2).
pub fn fhpp_event(t: u8) -> &'static str {
    match t {
        0x00 => "gone",
        0x01 => "fault",
        0x05 => "warning",
        0x07 => "switch-on",
        0x09 => "information",
        _ => "unknown",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_code_takes_its_manuals_text_or_its_own_or_its_class() {
        assert_eq!(cia_text(0x8611), "following error");
        assert_eq!(cia_text(0x8613), "positioning controller");
        assert_eq!(cia_text(0x4321), "temperature");
        assert_eq!(cia_text(0x8082), "limit switch: positive set-point blocked");
        // The manual's own text (App. B.2 43-1), not CiA 301's.
        assert_eq!(
            cia_error(devices::CMMP_AS.diagnostics, 0x8082).text,
            "Limit switch: positive setpoint blocked (message 43-1)"
        );
        // Each drive's own numbering and text, not the CMMP-AS's: the Nanotec's error bits.
        let nanotec = devices::by_name("nanotec-pd4n").unwrap().diagnostics;
        let row = nanotec.iter().find(|d| d.code.is_some()).unwrap();
        let code = row.code.unwrap();
        assert_eq!(
            cia_error(nanotec, code).text,
            format!("{} (message {})", row.text, row.number)
        );
        assert_eq!(cia_error(&[], 0x8082).text, cia_text(0x8082));
    }

    #[test]
    fn fhpp_numbers_take_the_app_d_name() {
        let app_d = devices::CMMO_ST.diagnostics;
        assert_eq!(fhpp_diagnostic(app_d, 0x4D).text, "Bootloader memory error");
        assert_eq!(fhpp_diagnostic(app_d, 0x4D).code, "4Dh");
    }
}
