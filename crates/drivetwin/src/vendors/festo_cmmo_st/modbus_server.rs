//! The CMMO-ST over Modbus TCP (manual GDCP-CMMO-ST-LK-C-HP §4.3): the [`RegisterMap`]
//! that puts the FHPP cyclic telegrams on Modbus registers, and the device as the runtime
//! serves it ([`ModbusDevice`], handed in as `vendors::MODBUS_DEVICE`): power-on with its
//! permanent memory ([`new_device`]), its cycle, what the console asks of it (objects,
//! diagnostics, plant).
//!
//! The register map, as the manual gives it:
//!
//! - **Start address 0 only, quantity 4 (FHPP Standard) or 8 (FHPP + FPC)**, big-endian
//!   registers (byte 1 of the telegram is the high byte of register 0). Writes (FC 0x10, the
//!   write half of 0x17) are the output telegram (CCON, CPOS, …); reads (FC 0x03, the read half
//!   of 0x17) are the input telegram (SCON, SPOS, …), never an echo of the outputs (§9.5).
//!   Decision (the manual says only "start address always 0" and "0x0004 / 0x0008"): another
//!   start address answers exception 02 (illegal data address), another quantity 03 (illegal
//!   data value); both quantities are accepted whatever the profile, the 8 FPC bytes of a
//!   16-byte write go to the parameter channel (registers 4…7, answered at the device's next
//!   cycle: `drive::vendors::festo_cmmo_st::fhpp::parameter_channel`), and FC 0x17 checks both halves before it
//!   writes anything.
//! - **FC 0x07** answers the active fault number (the diagnostic number, 0 = no fault).
//! - **FC 0x2B / 0x0E** (Tab. 4.4): 00 VendorName = PNU 122, 01 ProductCode = PNU 124,
//!   02 MajorMinorRevision = PNU 101 ("1.5.2.0"), 03 VendorUrl = PNU 123, 04 ProductName =
//!   PNU 120, 06 UserApplicationName = PNU 121 (read again whenever a client connects; an empty
//!   name is an empty object). Codes 01 and 02 only; the conformity level reported is the
//!   level of the request (01 / 02, stream access only), so code 04 answers 03.
//! - **Watchdog** (§4.3.4): when the server closes the connection because the client went
//!   silent ([`CloseReason::WatchdogExpired`]), diagnostic 47h "Modbus connection with master
//!   control" is raised when the fieldbus held device control, else 48h "… without master
//!   control" (a warning). The next client's connection removes the cause: 48h clears, 47h
//!   may then be acknowledged with CCON.RESET (it stays until then, visible in SCON.FAULT and
//!   FC 0x07).

use std::any::Any;
use std::time::Duration;

use drive::drive::diagnostics::DiagnosticError;
use drive::vendors::festo_cmmo_st::device::{diag, pnu_index, FhppDevice, FhppSettings};
use drive::vendors::festo_cmmo_st::fhpp::parameter_file::FormatError;
use modbus::{
    CloseReason, ConformityLevel, ConnectionEvent, Exception, ReadDeviceIdCode, RegisterMap,
};
use od::{AbortCode, Diagnostic, Instant, ObjectAccess};

use crate::cell::config::DriveSpec;
use crate::cell::control::{DisplayState, PhysicsChange, Plant, PlantPhysics};
use crate::cell::diagnostics::{Action, DiagnosticState};
use crate::cell::modbus_device::{ModbusDevice, NewDeviceError, PoweredOn, Readout};
use crate::cell::param_store::{ParamStore, StoreError};
use crate::cosim::{FmuLoad, FmuLoadError};
use drive::drive::named_switches::NamedSwitch;

/// Registers of the FHPP Standard telegram (8 bytes).
pub const STD_REGISTERS: usize = 4;
/// Registers of the FHPP + FPC telegram (16 bytes).
pub const FPC_REGISTERS: usize = 8;

/// The CMMO-ST's cycle (the FHPP device steps every millisecond).
pub const CYCLE: Duration = Duration::from_millis(1);

/// The CMMO-ST as the runtime serves it: the device, its Modbus register map (see the module
/// documentation) and where its permanent memory (PNU 127) is kept.
pub struct FhppModbus {
    device: FhppDevice<Vec<u8>>,
    /// Device identification objects 0x00…0x06 (index = object id).
    ident: [Vec<u8>; 7],
    /// Where its permanent memory is kept across restarts; `None`: for the life of the
    /// process only.
    store: Option<ParamStore>,
    /// The permanent memory's generation last written to `store`.
    generation: u32,
    /// The load FMU coupled to the shaft (`[drive.load]`), stepped with each FHPP cycle.
    load: Option<FmuLoad>,
    /// Why the load stopped the device (it steps no more).
    failure: Option<FmuLoadError>,
}

/// A char-array PNU (one ASCII code per subindex, 00h-padded) as bytes.
fn pnu_string(dev: &FhppDevice<Vec<u8>>, pnu: u16) -> Vec<u8> {
    (1u8..=30)
        .map_while(|sub| dev.read_u8(pnu_index(pnu), sub).filter(|c| *c != 0))
        .collect()
}

fn identification(dev: &FhppDevice<Vec<u8>>) -> [Vec<u8>; 7] {
    let version: Vec<String> = (1u8..=4)
        .map(|sub| dev.read_u16(pnu_index(101), sub).unwrap_or(0).to_string())
        .collect();
    [
        pnu_string(dev, 122),
        pnu_string(dev, 124),
        version.join(".").into_bytes(),
        pnu_string(dev, 123),
        pnu_string(dev, 120),
        Vec::new(), // 0x05 ModelName: not provided (Tab. 4.4 skips it)
        pnu_string(dev, 121),
    ]
}

impl FhppModbus {
    /// `device` served, its permanent memory kept in `store`.
    pub fn new(device: FhppDevice<Vec<u8>>, store: Option<ParamStore>) -> Self {
        let ident = identification(&device);
        let generation = device.permanent_memory().generation();
        FhppModbus {
            device,
            ident,
            store,
            generation,
            load: None,
            failure: None,
        }
    }

    pub fn device(&self) -> &FhppDevice<Vec<u8>> {
        &self.device
    }

    pub fn device_mut(&mut self) -> &mut FhppDevice<Vec<u8>> {
        &mut self.device
    }

    fn check(address: u16, quantity: usize) -> Result<(), Exception> {
        if address != 0 {
            return Err(Exception::IllegalDataAddress);
        }
        if quantity != STD_REGISTERS && quantity != FPC_REGISTERS {
            return Err(Exception::IllegalDataValue);
        }
        Ok(())
    }

    fn write_image(dev: &mut FhppDevice<Vec<u8>>, values: &[u16]) -> Result<(), Exception> {
        let mut image = [0u8; 16];
        for (chunk, v) in image.chunks_exact_mut(2).zip(values) {
            chunk.copy_from_slice(&v.to_be_bytes());
        }
        let bytes = image.get(..values.len() * 2).unwrap_or(&[]);
        dev.set_outputs(bytes)
            .map_err(|_| Exception::IllegalDataValue)
    }

    fn read_image(dev: &FhppDevice<Vec<u8>>, out: &mut [u16]) {
        let image = dev.inputs_fpc();
        for (r, chunk) in out.iter_mut().zip(image.chunks_exact(2)) {
            if let [hi, lo] = *chunk {
                *r = u16::from_be_bytes([hi, lo]);
            }
        }
    }

    /// Writes the permanent memory to its store when it changed since it was last written
    /// (PNU 127 save or delete, a parameter-file download).
    fn keep_memory(&mut self) {
        let Some(store) = &self.store else {
            return;
        };
        let memory = self.device.permanent_memory();
        if memory.generation() == self.generation {
            return;
        }
        self.generation = memory.generation();
        // CMMO-ST: saving takes the drive a moment as well; the cycle catches up afterwards.
        match store.save_memory(memory.stored()) {
            Ok(()) => {
                tracing::info!(path = %store.memory_path().display(), "permanent memory saved")
            }
            Err(e) => tracing::error!(error = %e, "permanent memory not saved"),
        }
    }
}

impl RegisterMap for FhppModbus {
    fn read(&mut self, address: u16, out: &mut [u16]) -> Result<(), Exception> {
        Self::check(address, out.len())?;
        Self::read_image(&self.device, out);
        Ok(())
    }

    fn write(&mut self, address: u16, values: &[u16]) -> Result<(), Exception> {
        Self::check(address, values.len())?;
        Self::write_image(&mut self.device, values)
    }

    fn read_write(
        &mut self,
        read_address: u16,
        out: &mut [u16],
        write_address: u16,
        values: &[u16],
    ) -> Result<(), Exception> {
        Self::check(read_address, out.len())?;
        Self::check(write_address, values.len())?;
        Self::write_image(&mut self.device, values)?;
        Self::read_image(&self.device, out);
        Ok(())
    }

    fn exception_status(&mut self) -> Result<u8, Exception> {
        Ok(self.device.fault_number())
    }

    fn device_id(&self, object: u8) -> Option<&[u8]> {
        match object {
            0x05 => None,
            _ => self.ident.get(usize::from(object)).map(Vec::as_slice),
        }
    }

    fn conformity_level(&self, requested: ReadDeviceIdCode) -> ConformityLevel {
        match requested {
            ReadDeviceIdCode::Basic => ConformityLevel::BASIC_STREAM,
            _ => ConformityLevel::REGULAR_STREAM,
        }
    }

    fn connection_event(&mut self, event: ConnectionEvent) {
        let dev = &mut self.device;
        match event {
            ConnectionEvent::Opened => {
                dev.clear_fault(diag::MODBUS_WITH_CONTROL);
                dev.clear_fault(diag::MODBUS_WITHOUT_CONTROL);
                self.ident = identification(dev);
            }
            ConnectionEvent::Closed(CloseReason::WatchdogExpired) => {
                let code = if dev.fieldbus_has_control() {
                    diag::MODBUS_WITH_CONTROL
                } else {
                    diag::MODBUS_WITHOUT_CONTROL
                };
                tracing::warn!(diagnostic = code, "Timeout MODBUS TCP/IP");
                dev.fault(code);
            }
            ConnectionEvent::Closed(_) => {}
        }
    }
}

impl ModbusDevice for FhppModbus {
    fn description(&self) -> &'static od::DeviceDescription {
        self.device.od().description()
    }

    fn od(&self) -> &od::ObjectDictionary<Vec<u8>> {
        self.device.od()
    }

    fn od_mut(&mut self) -> &mut od::ObjectDictionary<Vec<u8>> {
        self.device.od_mut()
    }

    fn access(&self) -> &dyn ObjectAccess {
        &self.device
    }

    fn access_mut(&mut self) -> &mut dyn ObjectAccess {
        &mut self.device
    }

    fn cycle(&self) -> Duration {
        CYCLE
    }

    fn step(&mut self, now: Instant) {
        match (&mut self.load, &self.failure) {
            (_, Some(_)) => {}
            (None, None) => {
                self.device.step(now);
            }
            (Some(load), None) => {
                if let Err(e) = self.device.step_with_load(now, load) {
                    tracing::error!(error = %e, "load FMU failed: the drive stops");
                    self.failure = Some(e);
                }
            }
        }
        self.keep_memory();
    }

    fn read_object(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, AbortCode> {
        ObjectAccess::read(&self.device, index, sub, buf)
    }

    fn write_object(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        ObjectAccess::write(&mut self.device, index, sub, data)
    }

    fn diagnostics(&self) -> Vec<DiagnosticState> {
        list_diagnostics(&self.device)
    }

    fn set_diagnostic(
        &mut self,
        number: &str,
        action: Action,
    ) -> Result<&'static Diagnostic, DiagnosticError> {
        set_diagnostic(&mut self.device, number, action)
    }

    fn physics(&mut self, change: PhysicsChange) -> Result<PlantPhysics, &'static str> {
        let d = &mut self.device;
        match change {
            PhysicsChange::None => {}
            PhysicsChange::Ambient(c) => d.set_ambient_temperature(c),
            PhysicsChange::Encoder(f) => d.set_encoder_fault(f),
            PhysicsChange::Thermal(t) => d.set_thermal_data(t),
            // Decision: the CMMO-ST's one switch input is the reference switch of homing
            // (§6.2), which `home` forces; its ends of travel are fixed stops, not inputs.
            PhysicsChange::Switch(NamedSwitch::Home, level) => d.force_reference_switch(level),
            PhysicsChange::Switch(s, _) => return Err(s.name()),
        }
        let w = d.plant_watch();
        Ok(PlantPhysics {
            ambient_c: w.thermal.ambient_c(),
            motor_c: w.thermal.motor_c(),
            power_stage_c: w.thermal.stage_c(),
            encoder: w.encoder.fault(),
            forced_inputs: (0, 0),
        })
    }

    fn set_load(&mut self, torque_nm: f64) {
        self.device.stepper_mut().set_load_torque(torque_nm);
    }

    fn plant(&self) -> (Plant, Option<DisplayState>) {
        let dev = &self.device;
        (
            Plant::Stepper {
                position_si: dev.actual_position_si(),
                load_torque_nm: dev.stepper().load_torque(),
            },
            Some(DisplayState::new(&dev.seven_segment().to_string())),
        )
    }

    fn readout(&self) -> Readout {
        let dev = &self.device;
        let stepper = dev.stepper();
        Readout {
            position_rad: stepper.angle(),
            velocity_rad_s: stepper.velocity(),
            current_a: stepper.current_a(),
            status: dev.inputs(),
            position_actual: dev.motion_status().actual_position,
        }
    }

    fn couple_load(&mut self, load: Option<FmuLoad>) -> Result<(), FmuLoadError> {
        if let Some(l) = &load {
            if let Some(s) = l.switches().find(|s| *s != NamedSwitch::Home) {
                return Err(FmuLoadError::NoInput {
                    fmu: l.name().to_string(),
                    device: "CMMO-ST",
                    switch: s.name(),
                });
            }
        }
        if self.load.take().is_some() {
            self.device.force_reference_switch(None);
            self.device.stepper_mut().set_load_torque(0.0);
        }
        self.failure = None;
        self.load = load;
        Ok(())
    }

    fn load_failure(&self) -> Option<&FmuLoadError> {
        self.failure.as_ref()
    }

    fn load(&self) -> Option<&FmuLoad> {
        self.load.as_ref()
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

/// Why a CMMO-ST powered on with its factory settings instead of its stored memory.
#[derive(Debug, thiserror::Error)]
pub enum PowerOnError {
    #[error("{0}; factory settings")]
    Store(#[from] StoreError),
    #[error("{path}: not a parameter file of this device ({error:?}); factory settings")]
    NotAParameterFile {
        path: std::path::PathBuf,
        error: FormatError,
    },
}

/// A CMMO-ST on the dictionary `od` (its defaults and commissioning values) with the cell
/// file's `settings`.
pub fn device(od: od::ObjectDictionary<Vec<u8>>, settings: FhppSettings) -> FhppDevice<Vec<u8>> {
    FhppDevice::new(od, settings)
}

/// Power-on: the permanent memory `store` kept becomes the device's, and its values active.
/// A file that cannot be read or is not a parameter file of this device (damaged, another
/// firmware) is reported and the device keeps its factory settings; the file stays for the
/// user to look at until the next save replaces it.
pub fn power_on(device: &mut FhppDevice<Vec<u8>>, store: &ParamStore) -> Result<(), PowerOnError> {
    match store.load_memory()? {
        None => Ok(()),
        Some(file) => {
            device
                .power_on_from_memory(&file)
                .map_err(|error| PowerOnError::NotAParameterFile {
                    path: store.memory_path().to_path_buf(),
                    error,
                })
        }
    }
}

/// The CMMO-ST of a cell file's drive at power-on (`vendors::MODBUS_DEVICE`): defaults, the
/// cell's commissioning values and settings, then its permanent memory from `store`; `None`
/// for a drive that is no CMMO-ST.
pub fn new_device(
    spec: &DriveSpec,
    store: Option<ParamStore>,
) -> Option<Result<PoweredOn, NewDeviceError>> {
    let fhpp = spec.fhpp.as_ref()?;
    let desc = spec.desc;
    let Ok(mut od) = od::ObjectDictionary::new(desc, 1, vec![0u8; desc.storage_size]) else {
        return Some(Err(NewDeviceError::Storage));
    };
    for c in &spec.commissioning {
        if let Some(e) = desc.entry(c.index, c.sub) {
            od.store(e, &c.bytes);
        }
    }
    let mut dev = device(od, fhpp.settings);
    let memory_error = store
        .as_ref()
        .and_then(|store| power_on(&mut dev, store).err())
        .map(|e| e.to_string());
    let mut served = FhppModbus::new(dev, store);
    if let Some(mapping) = &spec.load {
        let coupled = crate::cosim::FmuLoad::open(mapping, None, &format!("load{}", spec.node))
            .and_then(|load| served.couple_load(Some(load)));
        if let Err(e) = coupled {
            return Some(Err(NewDeviceError::Load(e.to_string())));
        }
    }
    Some(Ok(PoweredOn {
        device: Box::new(served),
        memory_error,
    }))
}

/// Raises (or clears) message `number` of the CMMO-ST.
pub fn set_diagnostic(
    dev: &mut FhppDevice<Vec<u8>>,
    number: &str,
    action: Action,
) -> Result<&'static Diagnostic, DiagnosticError> {
    let row = dev
        .od()
        .description()
        .diagnostic(number)
        .ok_or(DiagnosticError::Unknown)?;
    match action {
        Action::Raise => dev.raise_diagnostic(row.number).map(|_| ())?,
        Action::Clear => dev.clear_diagnostic(row.number)?,
    }
    Ok(row)
}

/// The CMMO-ST's App. D with what is active.
pub fn list_diagnostics(dev: &FhppDevice<Vec<u8>>) -> Vec<DiagnosticState> {
    dev.od()
        .description()
        .diagnostics
        .iter()
        .map(|row| DiagnosticState {
            row,
            emcy: None,
            active: drive::vendors::festo_cmmo_st::diagnostics::number(row.number)
                .is_some_and(|c| dev.diagnostic_active(c)),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use drive::vendors::festo_cmmo_st::device::FhppSettings;
    use modbus::handle_pdu;
    use od::ObjectDictionary;

    fn map() -> FhppModbus {
        let desc = &devices::CMMO_ST;
        let od = ObjectDictionary::new(desc, 1, vec![0u8; desc.storage_size]).unwrap();
        let dev = FhppDevice::new(od, FhppSettings::default());
        FhppModbus::new(dev, None)
    }

    fn pdu(m: &mut FhppModbus, req: &[u8]) -> Vec<u8> {
        let mut out = [0u8; 260];
        let n = handle_pdu(req, m, &mut out).unwrap();
        out[..n].to_vec()
    }

    /// The device's clock in a test, ms since power-on.
    struct Clock(u64);

    impl Clock {
        /// Steps the device `ms` cycles on.
        fn run(&mut self, m: &mut FhppModbus, ms: u64) {
            let d = &mut m.device;
            for _ in 0..ms {
                d.step(od::Instant::from_millis(self.0));
                self.0 += 1;
            }
        }
    }

    /// FC 0x17 with 4 registers each way: `out` is the output telegram.
    fn fc17(out: [u8; 8]) -> Vec<u8> {
        let mut req = vec![0x17, 0, 0, 0, 4, 0, 0, 0, 4, 8];
        req.extend_from_slice(&out);
        req
    }

    /// Enable, then home with the configured method (−35 by default: the current position
    /// is REF), over FC 0x17.
    fn enable_and_home(m: &mut FhppModbus, clock: &mut Clock) {
        pdu(m, &fc17([0x03, 0x01, 0, 0, 0, 0, 0, 0]));
        clock.run(m, 5);
        pdu(m, &fc17([0x03, 0x05, 0, 0, 0, 0, 0, 0]));
        clock.run(m, 50);
        let r = pdu(m, &fc17([0x03, 0x01, 0, 0, 0, 0, 0, 0]));
        assert_eq!(r[3] & 0x84, 0x84, "REF + MC: {r:02X?}");
    }

    fn step(m: &mut FhppModbus, ms: u64) {
        let d = &mut m.device;
        for t in 0..ms {
            d.step(od::Instant::from_millis(t));
        }
    }

    /// FHPP-MB-01, FHPP-MB-02: FC 10h writes `03 01 01 00 00 00 00 00` (answer `10 00 00 00
    /// 04`); FC 03h then reads the input telegram, SCON 13h, SPOS 05h; FHPP-CB-01 before it.
    #[test]
    fn power_on_then_enable_over_fc_0x17() {
        let mut m = map();
        step(&mut m, 2);
        assert_eq!(pdu(&mut m, &[0x03, 0, 0, 0, 4])[..4], [0x03, 8, 0x10, 0x04]);
        // FC 0x10 write the enable telegram (fhpp §8.2 a).
        let r = pdu(
            &mut m,
            &[0x10, 0, 0, 0, 4, 8, 0x03, 0x01, 0x01, 0, 0, 0, 0, 0],
        );
        assert_eq!(r, [0x10, 0, 0, 0, 4]);
        {
            let d = &mut m.device;
            d.step(od::Instant::from_millis(10));
        }
        let r = pdu(&mut m, &[0x03, 0, 0, 0, 4]);
        assert_eq!(r[..4], [0x03, 8, 0x13, 0x05], "{r:02X?}");
        let r = pdu(
            &mut m,
            &[
                0x17, 0, 0, 0, 4, 0, 0, 0, 4, 8, 0x03, 0x01, 0x01, 0, 0, 0, 0, 0,
            ],
        );
        assert_eq!(r[..4], [0x17, 8, 0x13, 0x05]);
    }

    /// FC 0x17 with 8 registers: registers 4…7 carry the EFPC (App. C); the answer comes
    /// with the device's next cycle.
    #[test]
    fn parameter_channel_over_fc_0x17_with_8_registers() {
        let mut m = map();
        step(&mut m, 1);
        let fc17 = |fpc: [u8; 8]| {
            let mut req = vec![0x17, 0, 0, 0, 8, 0, 0, 0, 8, 16, 0, 0, 0, 0, 0, 0, 0, 0];
            req.extend_from_slice(&fpc);
            req
        };
        let no_task = [0x10, 0, 0, 0, 0, 0, 0, 0];
        let read_101_1 = [0x16, 0x01, 0x00, 0x65, 0, 0, 0, 0];
        pdu(&mut m, &fc17(no_task));
        m.device.step(od::Instant::from_millis(1));
        let r = pdu(&mut m, &fc17(read_101_1));
        assert_eq!(r[..2], [0x17, 16]);
        assert_eq!(r[10..], no_task, "answered at the next cycle");
        m.device.step(od::Instant::from_millis(2));
        let r = pdu(&mut m, &fc17(read_101_1));
        // Firmware major version 1 (PNU 101:1), PNU and PWE big-endian.
        assert_eq!(r[10..], [0x15, 0x01, 0x00, 0x65, 0, 0, 0, 1]);
    }

    /// FHPP-MB-03 against the device's register map: referenced, direct mode S4; FC 17h with
    /// CCON 43h, CDIR 00h, 100 %, 00002710h; CPOS 01h → 03h. The answer once the device has
    /// run a cycle on it is `17 08 53 83 00 vv pp pp pp pp` (SPOS 83h = REF + ACK + HALT), then
    /// SPOS 93h while moving, finally SPOS & 07h = 05h after START is back to 0.
    #[test]
    fn fhpp_mb_03_direct_move_over_fc_0x17() {
        let mut m = map();
        let mut clock = Clock(0);
        clock.run(&mut m, 2);
        enable_and_home(&mut m, &mut clock);
        clock.run(&mut m, 5);
        // Cycle 1: direct mode, START = 0.
        let cycle1 = [0x43, 0x01, 0x00, 0x64, 0x00, 0x00, 0x27, 0x10];
        pdu(&mut m, &fc17(cycle1));
        clock.run(&mut m, 5);
        let r = pdu(&mut m, &fc17(cycle1));
        assert_eq!(r[..4], [0x17, 8, 0x53, 0x85], "{r:02X?}");
        // Cycle 2: START rising.
        let cycle2 = [0x43, 0x03, 0x00, 0x64, 0x00, 0x00, 0x27, 0x10];
        pdu(&mut m, &fc17(cycle2));
        clock.run(&mut m, 1);
        let r = pdu(&mut m, &fc17(cycle2));
        assert_eq!(r[..5], [0x17, 8, 0x53, 0x83, 0x00], "{r:02X?}");
        clock.run(&mut m, 50);
        let r = pdu(&mut m, &fc17(cycle2));
        assert_eq!(r[3], 0x93, "MOV while moving: {r:02X?}");
        assert!(r[4] == 0 && r[5] > 0, "SDIR absolute, velocity %: {r:02X?}");
        pdu(&mut m, &fc17(cycle1));
        let mut last = Vec::new();
        for _ in 0..300 {
            clock.run(&mut m, 10);
            last = pdu(&mut m, &fc17(cycle1));
            if last[3] & 0x04 != 0 {
                break;
            }
        }
        assert_eq!(last[3] & 0x07, 0x05, "MC, ACK = 0: {last:02X?}");
        let actual = i32::from_be_bytes([last[6], last[7], last[8], last[9]]);
        assert!((actual - 10_000).abs() <= 180, "at 10000 SINC: {actual}");
    }

    /// FHPP-MB-04, FHPP-FPC-01: FC 17h with quantity 8 / byte count 10h, EFPC `16 01 04 11 00
    /// 00 00 00` (read PNU 1041:1) after the zero request → `17 10 <8 status bytes> 15 01 04 11
    /// p3 p2 p1 p0`, the actual position big-endian as SPOS bytes 5…8 show it.
    #[test]
    fn fhpp_mb_04_read_pnu_1041_through_the_efpc() {
        let mut m = map();
        let mut clock = Clock(0);
        // Homing on the current position with the AZ offset PNU 1010 = 1234 SINC: the actual
        // position becomes −1234 (§6.2.1), a value with every byte set.
        m.device
            .write(pnu_index(1010), 1, &1234i32.to_le_bytes())
            .unwrap();
        clock.run(&mut m, 2);
        enable_and_home(&mut m, &mut clock);
        clock.run(&mut m, 2);
        let request = |fpc: [u8; 8]| {
            let mut req = vec![0x17, 0, 0, 0, 8, 0, 0, 0, 8, 0x10];
            req.extend_from_slice(&[0x43, 0x01, 0, 0, 0, 0, 0, 0]);
            req.extend_from_slice(&fpc);
            req
        };
        pdu(&mut m, &request([0x10, 0, 0, 0, 0, 0, 0, 0]));
        clock.run(&mut m, 2);
        let read_1041 = [0x16, 0x01, 0x04, 0x11, 0, 0, 0, 0];
        pdu(&mut m, &request(read_1041));
        clock.run(&mut m, 2);
        let r = pdu(&mut m, &request(read_1041));
        assert_eq!(r[..2], [0x17, 0x10]);
        assert_eq!(r[10..14], [0x15, 0x01, 0x04, 0x11], "{r:02X?}");
        let actual = m.device.read_u32(pnu_index(1041), 1);
        assert_eq!(
            Some(u32::from_be_bytes([r[14], r[15], r[16], r[17]])),
            actual
        );
        assert_eq!(r[14..18], (-1234i32).to_be_bytes(), "{r:02X?}");
        assert_eq!(r[14..18], r[6..10], "the same value as SPOS bytes 5…8");
    }

    /// FHPP-MB-05: FC 07h answers 00 without a fault and 2Fh with the following error active.
    #[test]
    fn fhpp_mb_05_exception_status_is_the_fault_number() {
        let mut m = map();
        step(&mut m, 2);
        assert_eq!(pdu(&mut m, &[0x07]), [0x07, 0x00]);
        {
            let d = &mut m.device;
            d.fault(diag::FOLLOWING_ERROR);
            for t in 2..10 {
                d.step(od::Instant::from_millis(t));
            }
        }
        assert_eq!(pdu(&mut m, &[0x07]), [0x07, 0x2F]);
    }

    #[test]
    fn wrong_address_and_quantity() {
        let mut m = map();
        assert_eq!(pdu(&mut m, &[0x03, 0, 1, 0, 4]), [0x83, 0x02]);
        assert_eq!(pdu(&mut m, &[0x03, 0, 0, 0, 5]), [0x83, 0x03]);
        assert_eq!(
            pdu(&mut m, &[0x10, 0, 0, 0, 2, 4, 0, 0, 0, 0]),
            [0x90, 0x03]
        );
        assert_eq!(
            pdu(
                &mut m,
                &[0x17, 0, 0, 0, 4, 0, 2, 0, 4, 8, 3, 1, 0, 0, 0, 0, 0, 0]
            ),
            [0x97, 0x02]
        );
        assert_eq!(pdu(&mut m, &[0x05, 0, 0, 0xFF, 0]), [0x85, 0x01]);
    }

    #[test]
    fn device_identification_basic_and_regular() {
        let mut m = map();
        let r = pdu(&mut m, &[0x2B, 0x0E, 0x01, 0x00]);
        assert_eq!(r[..7], [0x2B, 0x0E, 0x01, 0x01, 0x00, 0x00, 0x03]);
        let vendor = b"Festo AG & Co. KG";
        assert_eq!(r[7..9], [0x00, vendor.len() as u8]);
        assert_eq!(&r[9..9 + vendor.len()], vendor);
        let r = pdu(&mut m, &[0x2B, 0x0E, 0x02, 0x00]);
        assert_eq!(r[3], 0x02);
        assert_eq!(r[6], 6, "objects 00-04 and 06");
        let text = String::from_utf8_lossy(&r);
        assert!(text.contains("CMMO-ST-C5-1-LKP") && text.contains("http://www.festo.com"));
        assert!(text.contains("1.5.2.0"));
    }

    /// FHPP-DIAG-01, FHPP-MB-05: a watchdog timeout while Modbus holds control raises error
    /// 47h (SCON.FAULT, FC 0x07 answers 47h).
    #[test]
    fn watchdog_raises_47h_with_control_and_fc07_shows_it() {
        let mut m = map();
        step(&mut m, 2);
        assert_eq!(pdu(&mut m, &[0x07]), [0x07, 0x00]);
        m.connection_event(ConnectionEvent::Opened);
        m.connection_event(ConnectionEvent::Closed(CloseReason::WatchdogExpired));
        {
            let d = &mut m.device;
            for t in 2..10 {
                d.step(od::Instant::from_millis(t));
            }
        }
        assert_eq!(pdu(&mut m, &[0x07]), [0x07, 0x47]);
        let r = pdu(&mut m, &[0x03, 0, 0, 0, 4]);
        assert_eq!(r[2] & 0x08, 0x08, "SCON.FAULT");
        // A closed-by-peer connection raises nothing.
        let mut m = map();
        m.connection_event(ConnectionEvent::Closed(CloseReason::Peer));
        step(&mut m, 5);
        assert_eq!(pdu(&mut m, &[0x07]), [0x07, 0x00]);
    }

    /// FHPP-DIAG-01: a watchdog timeout while FCT holds control (Modbus has none) raises
    /// 48h, a warning: SCON.WARN, no fault (FC 0x07 answers 0), PNU 221 sub 3 bit 8; the next
    /// connection removes it.
    #[test]
    fn watchdog_without_control_warns_48h() {
        let mut m = map();
        step(&mut m, 2);
        m.device
            .fhpp_mut()
            .request_local_control(drive::vendors::festo_cmmo_st::fhpp::Authority::Fct)
            .unwrap();
        assert!(!m.device.fieldbus_has_control());
        m.connection_event(ConnectionEvent::Opened);
        m.connection_event(ConnectionEvent::Closed(CloseReason::WatchdogExpired));
        {
            let d = &mut m.device;
            for t in 2..10 {
                d.step(od::Instant::from_millis(t));
            }
            assert_eq!(d.read_u32(pnu_index(221), 3), Some(1 << (0x48 - 64)));
        }
        assert_eq!(pdu(&mut m, &[0x07]), [0x07, 0x00], "a warning is no fault");
        let r = pdu(&mut m, &[0x03, 0, 0, 0, 4]);
        assert_eq!(r[2] & 0x0C, 0x04, "SCON.WARN, not FAULT");
        m.connection_event(ConnectionEvent::Opened);
        {
            let d = &mut m.device;
            for t in 10..14 {
                d.step(od::Instant::from_millis(t));
            }
        }
        let r = pdu(&mut m, &[0x03, 0, 0, 0, 4]);
        assert_eq!(r[2] & 0x0C, 0x00, "cleared by the new connection");
    }
}
