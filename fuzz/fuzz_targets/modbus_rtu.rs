//! A Modbus RTU frame (address, PDU, CRC) into the CRC check and the server's PDU handling:
//! no panic, a frame whose CRC is wrong is never answered, an answer fits one RTU frame.
#![no_main]

use libfuzzer_sys::fuzz_target;
use modbus::{handle_pdu, Exception, RegisterMap, MAX_PDU_LEN};

struct Registers([u16; 64]);

impl RegisterMap for Registers {
    fn read(&mut self, address: u16, out: &mut [u16]) -> Result<(), Exception> {
        let start = usize::from(address);
        let src = self
            .0
            .get(start..start + out.len())
            .ok_or(Exception::IllegalDataAddress)?;
        out.copy_from_slice(src);
        Ok(())
    }

    fn write(&mut self, address: u16, values: &[u16]) -> Result<(), Exception> {
        let start = usize::from(address);
        let dst = self
            .0
            .get_mut(start..start + values.len())
            .ok_or(Exception::IllegalDataAddress)?;
        dst.copy_from_slice(values);
        Ok(())
    }

    fn exception_status(&mut self) -> Result<u8, Exception> {
        Ok(0)
    }
}

fuzz_target!(|data: &[u8]| {
    // Half the inputs get a right CRC, so the PDU handling behind the check is reached.
    let mut frame = data.to_vec();
    if data.first().is_some_and(|b| b & 1 == 1) && frame.len() >= 2 {
        let crc = modbus::rtu::crc_bytes(&frame);
        frame.extend_from_slice(&crc);
    }
    let Some(body) = modbus::rtu::strip_crc(&frame) else {
        assert!(!modbus::rtu::check_frame(&frame));
        return;
    };
    let Some((_address, pdu)) = body.split_first() else {
        return;
    };
    let mut map = Registers([0; 64]);
    let mut response = [0u8; MAX_PDU_LEN];
    if let Ok(n) = handle_pdu(pdu, &mut map, &mut response) {
        assert!((1..=MAX_PDU_LEN).contains(&n), "answer of {n} bytes");
    }
});
