//! A stand-in for the CMMO-ST's FHPP register image, as the manual lays it out (§4.3.2,
//! Tab. 4.3/4.4): start address 0, 4 registers (FHPP Standard) or 8 (FHPP + FPC), writes
//! go to the output image, reads come from the input image. The FHPP behaviour itself
//! (what SCON/SPOS become) belongs to the device; here the test sets the input image.
#![allow(dead_code)]
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use modbus::{ConformityLevel, ConnectionEvent, Exception, ReadDeviceIdCode, RegisterMap};

pub struct Cmmo {
    pub outputs: [u16; 8],
    pub inputs: [u16; 8],
    /// Device profile "FHPP Standard + FPC": 8 registers instead of 4.
    pub fpc: bool,
    /// Diagnostic number of the active fault, 0 = none (FC 0x07).
    pub fault: u8,
    pub writes: usize,
    pub events: Vec<ConnectionEvent>,
}

impl Cmmo {
    pub fn new(fpc: bool) -> Cmmo {
        Cmmo {
            outputs: [0; 8],
            // power-on: SCON 10h (VLOAD), SPOS 04h (MC), FHPP-CB-01
            inputs: [0x1004, 0, 0, 0, 0, 0, 0, 0],
            fpc,
            fault: 0,
            writes: 0,
            events: Vec::new(),
        }
    }

    fn check(&self, address: u16, quantity: usize) -> Result<usize, Exception> {
        if address != 0 {
            return Err(Exception::IllegalDataAddress);
        }
        match quantity {
            4 => Ok(4),
            8 if self.fpc => Ok(8),
            _ => Err(Exception::IllegalDataValue),
        }
    }
}

pub const VENDOR: &[u8] = b"Festo AG & Co. KG";
pub const PRODUCT_CODE: &[u8] = b"CMMO-ST-C5-1-LKP";
pub const REVISION: &[u8] = b"V1.5.2";
pub const URL: &[u8] = b"http://www.festo.com";
pub const PRODUCT_NAME: &[u8] = b"CMMO-ST-C5-1-LKP";
pub const APP_NAME: &[u8] = b"drivetwin";

impl RegisterMap for Cmmo {
    fn read(&mut self, address: u16, out: &mut [u16]) -> Result<(), Exception> {
        let n = self.check(address, out.len())?;
        out.copy_from_slice(&self.inputs[..n]);
        Ok(())
    }

    fn write(&mut self, address: u16, values: &[u16]) -> Result<(), Exception> {
        let n = self.check(address, values.len())?;
        self.outputs[..n].copy_from_slice(values);
        self.writes += 1;
        Ok(())
    }

    fn read_write(
        &mut self,
        read_address: u16,
        out: &mut [u16],
        write_address: u16,
        values: &[u16],
    ) -> Result<(), Exception> {
        // Both ranges are checked before anything is written.
        self.check(read_address, out.len())?;
        self.check(write_address, values.len())?;
        self.write(write_address, values)?;
        self.read(read_address, out)
    }

    fn exception_status(&mut self) -> Result<u8, Exception> {
        Ok(self.fault)
    }

    fn device_id(&self, object: u8) -> Option<&[u8]> {
        match object {
            0x00 => Some(VENDOR),
            0x01 => Some(PRODUCT_CODE),
            0x02 => Some(REVISION),
            0x03 => Some(URL),
            0x04 => Some(PRODUCT_NAME),
            0x06 => Some(APP_NAME),
            _ => None,
        }
    }

    /// Manual Tab. 4.3: conformity level "0x01 basic / 0x02 regular", the level asked for.
    fn conformity_level(&self, requested: ReadDeviceIdCode) -> ConformityLevel {
        match requested {
            ReadDeviceIdCode::Basic => ConformityLevel::BASIC_STREAM,
            _ => ConformityLevel::REGULAR_STREAM,
        }
    }

    fn connection_event(&mut self, event: ConnectionEvent) {
        self.events.push(event);
    }
}

/// Hex string ("00 01 0A") to bytes.
pub fn hex(s: &str) -> Vec<u8> {
    s.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).expect("hex byte"))
        .collect()
}

/// Runs one request ADU through `handle_adu`.
pub fn exchange(map: &mut impl RegisterMap, request: &[u8]) -> Result<Vec<u8>, modbus::AduError> {
    let mut out = [0u8; modbus::MAX_ADU_LEN];
    let n = modbus::handle_adu(request, map, &mut out)?;
    Ok(out[..n].to_vec())
}
