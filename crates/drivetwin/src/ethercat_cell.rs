//! An EtherCAT chain: emulated slave controllers (ESCs), each with the device behind it, that
//! one Ethernet frame passes in order, as a line of real slaves.
//!
//! Every slave is an [`Esc`] loaded with the SII image of its personality
//! (`ethercat::sii::build_sii`) and a [`SlaveDevice`]: the dictionary and, for a CiA 402
//! personality, the simulated drive and motor, built exactly as the CANopen cell builds them
//! (cell file, motor commissioning, [`CanDrive::with_settings`]).
//!
//! Process data (spec/cmmp-as-1-communication.md §2):
//!
//! * On Pre-Op → Safe-Op the device takes the PDO assignment (1C12h / 1C13h when the
//!   dictionary has them, else the SII defaults 1600h / 1A00h: the CMMP-AS maps its EtherCAT
//!   process data with the CANopen mapping objects 1600h–1603h / 1A00h–1A03h) and computes
//!   the bit layout of SM2 (outputs) and SM3 (inputs) from the mapping entries. A mapping the
//!   dictionary refuses is refused with 0x0025 (outputs) / 0x0024 (inputs); SM2 / SM3 sizes
//!   that do not match it with 0x001D / 0x001E ([`Esc::check_process_data`]).
//! * After every frame: the newest complete output buffer is written object by object through
//!   [`ObjectAccess::write`] in Op only (Safe-Op ignores set-points, CMMP-AS §4.2); the drive
//!   runs up to the frame's time; the mapped objects are read back into the input buffer
//!   (Safe-Op and Op), which the master reads with its next frame, one cycle later, as from
//!   a real ESC whose PDI runs beside the wire.
//! * Between frames the runtime polls the cell at least every [`TICK`], so the drive (and the
//!   ESC's process-data watchdog) runs while the master is silent.
//!
//! * The mailbox speaks CoE ([`ethercat::coe`], the CMMP-AS set of services): after every
//!   frame and every tick the device answers the request waiting in SM0 (or sends the next
//!   fragment or a queued emergency); the drive's errors go out as CoE emergencies.
//!
//! Not yet here: distributed-clock synchronisation of the drive (CSP on SYNC0, sync error
//! when cycles stop), stored parameters (1010h "save" is accepted and kept only until the
//! process ends), refusing mapping changes outside Pre-Op (a running layout is not affected:
//! it is taken on Pre-Op → Safe-Op).

use std::sync::Mutex;
use std::time::Duration;

use drive::drive::DriveEvent;
use ethercat::coe::{self, CoeConfig, CoeServer, Emergency};
use ethercat::sii::{self, SiiConfig};
use ethercat::{process_chain_with, AlHook, AlState, AlStatusCode, Esc, FrameOutcome};
use od::pdo_rules::{check_map_entry, MapEntry};
use od::{time::earliest, DeviceDescription, Instant, ObjectAccess};

use crate::can_drive::{CanDrive, DriveError};
use crate::cell_config::{CellFile, ConfigError, DriveSpec};
use crate::device_model::Model;

/// How often the drives run at least when no frame arrives.
pub const TICK: Duration = Duration::from_millis(1);

/// PDO assignment objects (ETG.1000.6): SM2 (RxPDO) and SM3 (TxPDO).
const RX_ASSIGN: u16 = 0x1C12;
const TX_ASSIGN: u16 = 0x1C13;

#[derive(Debug, thiserror::Error)]
pub enum EcatCellError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Drive(#[from] DriveError),
    #[error("{device}: no SII image: {error:?}")]
    Sii {
        device: &'static str,
        error: sii::SiiError,
    },
    #[error("an EtherCAT chain needs at least one slave")]
    Empty,
}

/// One mapped object in a process image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MapItem {
    pub index: u16,
    pub sub: u8,
    /// Bit offset in the process image.
    pub offset: usize,
    pub bits: u8,
    /// A dummy entry (RxPDO gap): skipped.
    pub dummy: bool,
}

/// The process-data layout taken on Pre-Op → Safe-Op.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Layout {
    /// SM2, master → device.
    pub outputs: Vec<MapItem>,
    /// SM3, device → master.
    pub inputs: Vec<MapItem>,
    pub output_bytes: u16,
    pub input_bytes: u16,
}

/// The device behind one ESC; it is the ESC's [`AlHook`].
pub struct SlaveDevice {
    pub model: Model,
    coe: Box<CoeServer>,
    sii: SiiConfig<'static>,
    layout: Option<Layout>,
    inputs: Vec<u8>,
    next_step: Option<Instant>,
    /// Output buffers applied to the device (Op).
    pub outputs_applied: u64,
    /// Output buffers ignored (Safe-Op).
    pub outputs_ignored: u64,
    /// Mapped objects the device refused to take.
    pub write_errors: u64,
}

impl SlaveDevice {
    pub fn new(model: Model, sii: SiiConfig<'static>, coe: CoeConfig) -> Self {
        let desc = model.od().description();
        SlaveDevice {
            model,
            coe: Box::new(CoeServer::new(desc, coe)),
            sii,
            layout: None,
            inputs: Vec::new(),
            next_step: None,
            outputs_applied: 0,
            outputs_ignored: 0,
            write_errors: 0,
        }
    }

    /// The layout in force (Safe-Op and Op).
    pub fn layout(&self) -> Option<&Layout> {
        self.layout.as_ref()
    }

    /// The PDO assignment of SM2 or SM3: 1C12h / 1C13h from the dictionary when it has
    /// them, else the SII's defaults.
    fn assignment(&self, rx: bool) -> Result<Vec<u16>, ()> {
        let index = if rx { RX_ASSIGN } else { TX_ASSIGN };
        if self.model.entry(index, 0).is_err() {
            let d = if rx {
                self.sii.rx_assigned
            } else {
                self.sii.tx_assigned
            };
            return Ok(d.to_vec());
        }
        let count = read_unsigned(&self.model, index, 0).ok_or(())?;
        (1..=count)
            .map(|sub| {
                let sub = u8::try_from(sub).map_err(|_| ())?;
                read_unsigned(&self.model, index, sub)
                    .and_then(|v| u16::try_from(v).ok())
                    .ok_or(())
            })
            .collect()
    }

    /// The items of one direction from the current mapping objects, and the bit length.
    fn map(&self, rx: bool) -> Result<(Vec<MapItem>, usize), ()> {
        let desc = self.model.od().description();
        let mut items = Vec::new();
        let mut offset = 0usize;
        for pdo in self.assignment(rx)? {
            let count = read_unsigned(&self.model, pdo, 0).ok_or(())?;
            for sub in 1..=count {
                let sub = u8::try_from(sub).map_err(|_| ())?;
                let v = read_unsigned(&self.model, pdo, sub).ok_or(())?;
                let v = u32::try_from(v).map_err(|_| ())?;
                if v == 0 {
                    continue;
                }
                check_map_entry(desc, !rx, v).map_err(|_| ())?;
                let m = MapEntry::from_u32(v);
                items.push(MapItem {
                    index: m.index,
                    sub: m.sub,
                    offset,
                    bits: m.bits,
                    dummy: m.is_dummy(),
                });
                offset += usize::from(m.bits);
            }
        }
        Ok((items, offset))
    }

    /// The layout the current dictionary gives, or the AL status code that refuses it.
    pub fn compute_layout(&self) -> Result<Layout, AlStatusCode> {
        let (outputs, out_bits) = self
            .map(true)
            .map_err(|()| AlStatusCode::INVALID_OUTPUT_MAPPING)?;
        let (inputs, in_bits) = self
            .map(false)
            .map_err(|()| AlStatusCode::INVALID_INPUT_MAPPING)?;
        Ok(Layout {
            outputs,
            inputs,
            output_bytes: u16::try_from(out_bits.div_ceil(8))
                .map_err(|_| AlStatusCode::INVALID_OUTPUT_MAPPING)?,
            input_bytes: u16::try_from(in_bits.div_ceil(8))
                .map_err(|_| AlStatusCode::INVALID_INPUT_MAPPING)?,
        })
    }

    /// Writes the mapped objects of an output buffer into the device.
    fn apply_outputs(&mut self, data: &[u8]) {
        let Some(layout) = &self.layout else {
            return;
        };
        let mut value = [0u8; 8];
        for item in layout.outputs.iter().filter(|i| !i.dummy) {
            let n = usize::from(item.bits).div_ceil(8);
            let Some(v) = value.get_mut(..n) else {
                continue;
            };
            get_bits(data, item.offset, item.bits, v);
            if self.model.write(item.index, item.sub, v).is_err() {
                self.write_errors += 1;
            }
        }
    }

    /// Reads the mapped objects into the input buffer and hands it to the ESC.
    fn post_inputs(&mut self, esc: &mut Esc<'_>) {
        let Some(layout) = &self.layout else {
            return;
        };
        self.inputs.clear();
        self.inputs.resize(usize::from(layout.input_bytes), 0);
        let mut value = [0u8; 8];
        for item in &layout.inputs {
            value.fill(0);
            // A value that cannot be read leaves zeros, as a real PDI would leave stale data.
            let _ = self.model.read(item.index, item.sub, &mut value);
            set_bits(&mut self.inputs, item.offset, item.bits, &value);
        }
        if !self.inputs.is_empty() {
            let _ = esc.set_inputs(&self.inputs);
        }
    }

    /// The device's part of a frame: outputs in, drive to `now`, inputs out.
    fn exchange(&mut self, esc: &mut Esc<'_>, now: Instant) {
        self.step(now);
        let state = esc.al_state();
        if let Some(out) = esc.process_outputs() {
            if state == AlState::Op {
                self.apply_outputs(out);
                self.outputs_applied += 1;
            } else {
                self.outputs_ignored += 1;
            }
        }
        self.post_inputs(esc);
        self.mailbox(esc);
    }

    /// Serves the mailbox once (CoE), then what the dictionary asked for (1010h / 1011h).
    fn mailbox(&mut self, esc: &mut Esc<'_>) {
        coe::pump(esc, &mut self.coe, &mut self.model);
        if let Some(req) = self.model.od_mut().take_request() {
            match req {
                od::StorageRequest::Save { .. } => {
                    tracing::warn!("save accepted, but the EtherCAT chain keeps no state")
                }
                od::StorageRequest::Restore { .. } => self.model.reload(),
            }
        }
    }

    /// CoE counters (requests, aborts, emergencies).
    pub fn coe_counters(&self) -> coe::CoeCounters {
        self.coe.counters()
    }

    fn step(&mut self, now: Instant) {
        self.next_step = self.model.step(now).map(|t| t.max(now + TICK));
        while let Some(ev) = self.model.take_event() {
            // CiA 402 errors as CoE emergencies (ETG.1000.6 §5.6.4, the CANopen EMCY layout).
            let emcy = match ev {
                DriveEvent::Error { code, register } => Emergency::new(code, register, [0; 5]),
                // "Error reset": code 0000h with the error register that remains.
                DriveEvent::Cleared { .. } => {
                    let register = read_unsigned(&self.model, 0x1001, 0).unwrap_or(0);
                    Emergency::new(0, u8::try_from(register).unwrap_or(0), [0; 5])
                }
            };
            if self.coe.queue_emergency(emcy).is_err() {
                tracing::warn!(event = ?ev, "emergency queue full");
            }
        }
    }
}

impl AlHook for SlaveDevice {
    fn check_transition(
        &mut self,
        esc: &Esc<'_>,
        from: AlState,
        to: AlState,
    ) -> Result<(), AlStatusCode> {
        if from == AlState::PreOp && to == AlState::SafeOp {
            let layout = self.compute_layout()?;
            esc.check_process_data(layout.output_bytes, layout.input_bytes)?;
            self.layout = Some(layout);
        }
        Ok(())
    }

    fn state_changed(&mut self, esc: &mut Esc<'_>, from: AlState, to: AlState) {
        tracing::debug!(?from, ?to, station = esc.station_address(), "AL state");
        match to {
            AlState::SafeOp | AlState::Op => self.post_inputs(esc),
            AlState::Init | AlState::PreOp | AlState::Bootstrap => self.layout = None,
        }
    }
}

fn read_unsigned(dev: &dyn ObjectAccess, index: u16, sub: u8) -> Option<u64> {
    let mut b = [0u8; 8];
    let n = dev.read(index, sub, &mut b).ok()?;
    (n <= 8).then(|| u64::from_le_bytes(b))
}

/// Copies `bits` bits from `src` at bit offset `offset` into `dst` (LSB first).
fn get_bits(src: &[u8], offset: usize, bits: u8, dst: &mut [u8]) {
    dst.fill(0);
    for i in 0..usize::from(bits) {
        let s = offset + i;
        let bit = src.get(s / 8).map(|b| (b >> (s % 8)) & 1).unwrap_or(0);
        if let Some(d) = dst.get_mut(i / 8) {
            *d |= bit << (i % 8);
        }
    }
}

/// Copies the low `bits` bits of `src` into `dst` at bit offset `offset` (LSB first).
fn set_bits(dst: &mut [u8], offset: usize, bits: u8, src: &[u8]) {
    for i in 0..usize::from(bits) {
        let bit = src.get(i / 8).map(|b| (b >> (i % 8)) & 1).unwrap_or(0);
        let d = offset + i;
        if let Some(b) = dst.get_mut(d / 8) {
            *b = (*b & !(1 << (d % 8))) | (bit << (d % 8));
        }
    }
}

/// The SII image of a personality, built once per process.
pub fn sii_image(
    desc: &'static DeviceDescription,
    cfg: &SiiConfig<'static>,
) -> Result<&'static [u8], EcatCellError> {
    type Cache = Vec<(&'static str, SiiConfig<'static>, &'static [u8])>;
    static CACHE: Mutex<Cache> = Mutex::new(Vec::new());
    let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((_, _, image)) = cache.iter().find(|(n, c, _)| *n == desc.name && c == cfg) {
        return Ok(image);
    }
    let mut buf = vec![0u8; sii::DEFAULT_IMAGE_SIZE];
    sii::build_sii(desc, cfg, &mut buf).map_err(|error| EcatCellError::Sii {
        device: desc.name,
        error,
    })?;
    // One image per personality and configuration for the life of the process.
    let image: &'static [u8] = Box::leak(buf.into_boxed_slice());
    cache.push((desc.name, *cfg, image));
    Ok(image)
}

/// The chain: `escs[i]` with `devices[i]`, in wire order.
pub struct EthercatCell {
    escs: Vec<Esc<'static>>,
    devices: Vec<SlaveDevice>,
    /// Frames processed (EtherCAT or not).
    pub frames: u64,
}

impl EthercatCell {
    /// One slave per drive of the cell file, in file order. Node-IDs only name the drives;
    /// EtherCAT addresses them by position and station address.
    pub fn from_cell_file(file: &CellFile) -> Result<Self, EcatCellError> {
        Self::new(file.drives()?)
    }

    pub fn new(specs: Vec<DriveSpec>) -> Result<Self, EcatCellError> {
        if specs.is_empty() {
            return Err(EcatCellError::Empty);
        }
        let mut escs = Vec::with_capacity(specs.len());
        let mut devices = Vec::with_capacity(specs.len());
        for spec in specs {
            let cfg = SiiConfig::CMMP_AS;
            let image = sii_image(spec.desc, &cfg)?;
            let settings = spec.settings.map(|mut s| {
                // CSP (6060h = 8) exists only over EtherCAT.
                s.ethercat = true;
                s
            });
            let drive =
                CanDrive::with_settings(spec.desc, spec.node, None, spec.commissioning, settings)?;
            escs.push(Esc::with_sii(image));
            devices.push(SlaveDevice::new(drive.model, cfg, CoeConfig::CMMP_AS));
        }
        Ok(EthercatCell {
            escs,
            devices,
            frames: 0,
        })
    }

    pub fn len(&self) -> usize {
        self.escs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.escs.is_empty()
    }

    pub fn esc(&self, i: usize) -> Option<&Esc<'static>> {
        self.escs.get(i)
    }

    pub fn device(&self, i: usize) -> Option<&SlaveDevice> {
        self.devices.get(i)
    }

    pub fn device_mut(&mut self, i: usize) -> Option<&mut SlaveDevice> {
        self.devices.get_mut(i)
    }

    /// Power-on: the drives start their clocks.
    pub fn boot(&mut self, now: Instant) {
        for d in &mut self.devices {
            d.step(now);
        }
    }

    /// A frame from the master, processed in place through every slave in order; then each
    /// device exchanges its process data. Send the frame back when
    /// [`FrameOutcome::forward`] says so.
    pub fn on_frame(&mut self, now: Instant, frame: &mut [u8]) -> FrameOutcome {
        self.frames += 1;
        let outcome = process_chain_with(&mut self.escs, &mut self.devices, now, frame);
        for (esc, dev) in self.escs.iter_mut().zip(self.devices.iter_mut()) {
            dev.exchange(esc, now);
        }
        outcome
    }

    /// Time passes without a frame: drives run, ESC watchdogs are checked, inputs refreshed.
    /// Returns the next deadline.
    pub fn poll(&mut self, now: Instant) -> Option<Instant> {
        for (esc, dev) in self.escs.iter_mut().zip(self.devices.iter_mut()) {
            dev.step(now);
            esc.poll_with(now, dev);
            if matches!(esc.al_state(), AlState::SafeOp | AlState::Op) {
                dev.post_inputs(esc);
            }
            dev.mailbox(esc);
        }
        self.deadline()
    }

    pub fn deadline(&self) -> Option<Instant> {
        self.devices
            .iter()
            .fold(None, |acc, d| earliest(acc, d.next_step))
    }
}

/// Runs `cell` on `socket` in real time until `shutdown` completes (or the socket fails).
#[cfg(target_os = "linux")]
pub async fn run_realtime(
    mut cell: EthercatCell,
    socket: crate::ethercat_link::EthercatSocket,
    shutdown: impl std::future::Future<Output = ()>,
) -> std::io::Result<()> {
    use crate::ethercat_link::{is_queue_full, MAX_FRAME};
    let start = tokio::time::Instant::now();
    let now = || Instant::from_nanos(u64::try_from(start.elapsed().as_nanos()).unwrap_or(u64::MAX));
    cell.boot(now());
    let mut buf = vec![0u8; MAX_FRAME];
    tokio::pin!(shutdown);
    loop {
        let wake = cell
            .deadline()
            .map(|d| start + Duration::from_nanos(d.as_nanos()))
            .unwrap_or_else(|| tokio::time::Instant::now() + TICK);
        let received = tokio::select! {
            biased;
            _ = &mut shutdown => return Ok(()),
            r = socket.recv(&mut buf) => Some(r?),
            _ = tokio::time::sleep_until(wake) => None,
        };
        match received {
            Some(n) => {
                let Some(frame) = buf.get_mut(..n) else {
                    continue;
                };
                if cell.on_frame(now(), frame).forward() {
                    match socket.send(frame).await {
                        Ok(()) => {}
                        Err(e) if is_queue_full(&e) => {
                            tracing::warn!(interface = %socket.interface(), "TX queue full, frame lost");
                        }
                        Err(e) => return Err(e),
                    }
                }
            }
            None => {
                cell.poll(now());
            }
        }
    }
}
