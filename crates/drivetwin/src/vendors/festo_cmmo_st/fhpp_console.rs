//! The FHPP side of a running CMMO-ST for the console: its telegrams, control authority and
//! diagnostic memory, and the console's requests on them (the motion page's FHPP buttons and
//! the device's own web server). A request runs on the drive in the loop's thread through
//! [`ControlHandle::with_modbus_device`].

use drive::vendors::festo_cmmo_st::device::FhppDevice;
use drive::vendors::festo_cmmo_st::fhpp::Authority;

use super::modbus_server::FhppModbus;
use crate::cell::control::{ControlError, ControlHandle};

/// What [`fhpp`] asks of a CMMO-ST.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FhppRequest {
    /// Nothing: the state only.
    Status,
    /// The 8-byte output telegram (CCON, CPOS, …) as a fieldbus master writes it; taken at
    /// the drive's next cycle.
    SetOutputs([u8; 8]),
    /// The web server takes device control (`true`) or gives it back to the fieldbus (CMMO-ST
    /// §2.2 "Device Control", PNU 125 §3.1.1); refused while the PLC sets CCON.LOCK.
    DeviceControl(bool),
}

/// A CMMO-ST's FHPP state.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FhppState {
    /// The input telegram of the last cycle: SCON, SPOS, byte 3…8.
    pub inputs: [u8; 8],
    /// The output telegram in force.
    pub outputs: [u8; 8],
    /// Who holds device control.
    pub authority: Authority,
    /// The active fault's diagnostic number (0: none).
    pub fault: u8,
    /// The diagnostic memory, newest first: (PNU 200 event type, PNU 201 number, PNU 202 ms).
    pub memory: Vec<(u8, u16, u32)>,
    /// Why a [`FhppRequest::DeviceControl`] was refused (the parameter-channel error number).
    pub refused: Option<u8>,
}

/// The FHPP side of CMMO-ST `drive` after `request` is carried out; a drive that is no
/// CMMO-ST has none ([`ControlError::NoPlant`]).
pub fn fhpp(
    h: &ControlHandle,
    drive: usize,
    request: FhppRequest,
) -> Result<FhppState, ControlError> {
    h.with_modbus_device(drive, move |device| {
        let served = device?
            .as_any_mut()
            .downcast_mut::<FhppModbus>()
            .ok_or(ControlError::NoPlant(drive))?;
        Ok(console_request(served.device_mut(), request))
    })
}

/// A request of the web console on the CMMO-ST's FHPP side, and its state after it.
pub fn console_request(dev: &mut FhppDevice<Vec<u8>>, request: FhppRequest) -> FhppState {
    let mut refused = None;
    match request {
        FhppRequest::Status => {}
        FhppRequest::SetOutputs(image) => {
            // Eight bytes are always a valid FHPP Standard telegram.
            let _ = dev.set_outputs(&image);
        }
        FhppRequest::DeviceControl(true) => {
            if let Err(e) = dev.fhpp_mut().request_local_control(Authority::WebServer) {
                refused = Some(e.fpc_error());
            }
        }
        FhppRequest::DeviceControl(false) => {
            if dev.fhpp().authority() == Authority::WebServer {
                dev.fhpp_mut().release_local_control();
            }
        }
    }
    FhppState {
        inputs: dev.inputs(),
        outputs: dev.outputs().to_bytes(),
        authority: dev.fhpp().authority(),
        fault: dev.fault_number(),
        memory: dev
            .diagnostic_memory()
            .iter()
            .map(|e| (e.event.value(), e.number, e.time_ms))
            .collect(),
        refused,
    }
}
