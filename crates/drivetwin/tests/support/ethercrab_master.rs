//! What the ethercrab tests share: the sizes of ethercrab's storage for one CMMP-AS, the
//! twin's identity, and a MainDevice with timeouts a shared CI machine keeps.
#![allow(dead_code)] // each test file uses a part of it

use std::path::Path;
use std::process::Command;
use std::time::Duration;

use ethercrab::error::Error;
use ethercrab::std::tx_rx_task;
use ethercrab::{MainDevice, MainDeviceConfig, PduRx, PduStorage, PduTx, RetryBehaviour, Timeouts};
use platform::sched::Scheduling;

pub const FESTO: u32 = 0x1D;
pub const MAX_SUBDEVICES: usize = 2;
pub const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
pub const MAX_FRAMES: usize = 16;
pub const PDI_LEN: usize = 64;
/// LRW working counter for one slave with outputs written (+2) and inputs read (+1).
pub const EXPECTED_WKC: u16 = 3;
/// Default following-error window 6065h of the CMMP-AS.
pub const FOLLOWING_ERROR_WINDOW: i32 = 9101;

/// ethercrab's storage for the frames of one MainDevice (it splits once).
pub type Storage = PduStorage<MAX_FRAMES, MAX_PDU_DATA>;

/// The product code the twin's ESI declares (`<Type ProductCode="#x0018C375" ...>`).
pub fn esi_product_code(binary: &Path) -> u32 {
    let out = Command::new(binary)
        .args(["esi", "--device", "cmmp-as"])
        .output()
        .expect("drivetwin esi");
    assert!(out.status.success(), "drivetwin esi: {out:?}");
    let xml = String::from_utf8_lossy(&out.stdout);
    let key = "ProductCode=\"#x";
    let start = xml.find(key).expect("ProductCode in the ESI") + key.len();
    let hex: String = xml[start..]
        .chars()
        .take_while(|c| c.is_ascii_hexdigit())
        .collect();
    u32::from_str_radix(&hex, 16).expect("hex product code")
}

/// ethercrab's TX/RX task; it ends with the (released) storage halves, or an error.
pub type TxRxTask = tokio::task::JoinHandle<Result<(PduTx<'static>, PduRx<'static>), Error>>;

/// A MainDevice on `master_if` with ethercrab's std TX/RX task running; a group state change
/// may take `state_transition`.
pub fn main_device(
    storage: &'static Storage,
    master_if: &str,
    state_transition: Duration,
) -> (MainDevice<'static>, TxRxTask) {
    let (tx, rx, pdu_loop) = storage.try_split().expect("PDU storage split once");
    let maindevice = MainDevice::new(
        pdu_loop,
        Timeouts {
            // The twin answers in well under a millisecond, but a shared CI machine can hold
            // either process off the CPU for a while (as in the pysoem test).
            pdu: Duration::from_millis(100),
            // An SII read waits for the busy flag with FPRDs; the default 10 ms covers only a
            // few round trips on such a machine.
            eeprom: Duration::from_millis(100),
            state_transition,
            ..Timeouts::default()
        },
        MainDeviceConfig {
            retry_behaviour: RetryBehaviour::None,
            // ethercrab's default: 10 000 FRMW 0910h to the reference clock during init.
            ..MainDeviceConfig::default()
        },
    );
    let task =
        tokio::spawn(tx_rx_task(master_if, tx, rx).expect("open the master-side raw socket"));
    (maindevice, task)
}

/// RxPDO3 as the tests map it: controlword, then the CSP target position.
pub fn put_csp_outputs(out: &mut [u8], controlword: u16, target: i32) {
    out[..2].copy_from_slice(&controlword.to_le_bytes());
    out[2..6].copy_from_slice(&target.to_le_bytes());
}

/// TxPDO3 as the tests map it: statusword, then the position actual value.
pub fn csp_inputs(inputs: &[u8]) -> (u16, i32) {
    (
        u16::from_le_bytes([inputs[0], inputs[1]]),
        i32::from_le_bytes([inputs[2], inputs[3], inputs[4], inputs[5]]),
    )
}

/// RxPDO3 / TxPDO3 assigned (1C12h / 1C13h) and CSP selected (6060h = 8, EtherCAT only) over
/// CoE in Pre-Op, as the pysoem test does; ethercrab then sizes SM2/SM3 and the FMMUs from
/// them.
pub async fn assign_csp_pdos<S>(slave: &ethercrab::SubDeviceRef<'_, S>)
where
    S: std::ops::Deref<Target = ethercrab::SubDevice>,
{
    slave
        .sdo_write_array(0x1C12, [0x1602u16])
        .await
        .expect("1C12h");
    slave
        .sdo_write_array(0x1C13, [0x1A02u16])
        .await
        .expect("1C13h");
    slave.sdo_write(0x6060, 0, 8i8).await.expect("6060h = CSP");
}

/// The master's threads at SCHED_FIFO 20 while this lives, where allowed (the thread that
/// enters it and the threads it starts: ethercrab's reactor thread of async-io), as a PLC runs
/// its EtherCAT task; the old policy comes back on drop. Beside the twin at `--rt-priority 20`.
pub struct Realtime(Option<Scheduling>);

impl Realtime {
    pub fn enter() -> Self {
        let Ok(old) = Scheduling::of_this_thread() else {
            return Realtime(None);
        };
        if platform::sched::set_fifo(0, 20).is_err() {
            eprintln!("SCHED_FIFO refused: the master runs at normal priority");
            return Realtime(None);
        }
        Realtime(Some(old))
    }
}

impl Drop for Realtime {
    fn drop(&mut self) {
        if let Some(old) = self.0 {
            let _ = old.restore();
        }
    }
}

/// The runtime the master's session runs on: one thread, as a PLC's EtherCAT task sends and
/// receives its frames on one thread. The cycle's wait is a thread sleep in that thread (finer
/// than tokio's 1 ms timer), with no frame in flight; ethercrab's TX/RX task runs on it while
/// the session awaits a frame. A frame's round trip then passes three threads (this one, the
/// twin's loop, the reactor thread of async-io that ethercrab's socket waits on) rather than
/// five with a pool of workers: on a shared 2-CPU machine each thread woken on the way may
/// wait behind a neighbour that holds its CPU in the kernel for milliseconds (the kernel runs
/// `preempt=none`), or on a virtual CPU the host has not scheduled (docs/performance.md).
pub fn master_runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("tokio runtime")
}
