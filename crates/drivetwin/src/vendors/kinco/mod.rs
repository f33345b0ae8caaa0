//! The Kinco FD3 / CD3 (`drive::vendors::kinco`): its serial lines (the RS232 telegrams,
//! Kinco manual ch. 10, and Modbus RTU on RS485, ch. 12, served at the same time as CANopen,
//! all on the same objects), its LED panel on the web console and a master for its RS232
//! telegrams.
//!
//! - [`rs232_line`]: the telegram protocol on a line, point to point, a ring, or on RS485;
//! - [`rtu_line`]: Modbus RTU on an RS485 line, frames cut by the 3.5-character silence,
//!   several drives by station number;
//! - [`serial_lines`]: the lines of a cell from the drives' ports and their objects;
//! - [`cell_section`]: the FD3's and the CD3's keys of a cell file (DIP switches, ports).

pub mod cell_section;
pub mod panel_page;
pub mod rs232_commands;
pub mod rs232_line;
pub mod rs232_master;
pub mod rtu_line;
pub mod serial_lines;

use crate::web::DevicePages;

/// The panel's REST API (`/api/drives/{drive}/panel`).
pub const WEB_PAGES: DevicePages = DevicePages {
    routes: panel_page::routes,
    openapi: <panel_page::PanelDoc as utoipa::OpenApi>::openapi,
    motion: None,
};

/// The bit rate of a Kinco baud-rate code (2FE0h, 2FE1h, 2FE2h): the device file's
/// `serial_bit_rate` table (§9.5, KINCO-232-10); `None` for a code it does not list.
pub fn baud_of_code(codes: &od::SerialBitRateCodes, code: u64) -> Option<u32> {
    u16::try_from(code).ok().and_then(|c| codes.bit_rate(c))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// KINCO-232-10: the codes the FD3's and the CD3's device files list, and no others.
    #[test]
    fn kinco_232_10_baud_rate_codes() {
        for desc in [&devices::KINCO_FD3, &devices::KINCO_CD3] {
            let codes = desc.serial_bit_rate.as_ref().expect("serial_bit_rate");
            assert_eq!(baud_of_code(codes, 540), Some(19_200));
            assert_eq!(baud_of_code(codes, 270), Some(38_400));
            assert_eq!(baud_of_code(codes, 90), Some(115_200));
            assert_eq!(baud_of_code(codes, 1080), Some(9600));
            assert_eq!(baud_of_code(codes, 0), None);
            // 180 would be 57600 by the formula, but the manual lists no such code.
            assert_eq!(baud_of_code(codes, 180), None);
            assert_eq!(baud_of_code(codes, 0x1_0000 + 270), None);
        }
    }
}
