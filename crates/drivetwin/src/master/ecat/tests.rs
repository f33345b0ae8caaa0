//! The master against the twin's own EtherCAT chain, in process: every frame goes through
//! [`SlaveChain::on_frame`] as it would through `drivetwin run --ethercat`.

use std::io;
use std::time::Duration;

use ethercat::datagram::{Command, Datagram};
use ethercat::frame::{self, Frame};
use ethercat::master::reply_datagram;
use ethercat::{AlState, AlStatusCode};
use od::{AbortCode, Instant};

use super::*;
use crate::cell::config::CellFile;
use crate::ecat::chain::SlaveChain;

/// The chain on a virtual clock (100 µs per frame); requests are recorded.
pub(crate) struct CellLink {
    pub cell: SlaveChain,
    now_ns: u64,
    pub sent: Vec<Vec<u8>>,
}

impl CellLink {
    pub fn new(devices: &[&str]) -> Self {
        let mut specs = Vec::new();
        for (i, d) in devices.iter().enumerate() {
            let node = u8::try_from(i + 1).expect("few slaves");
            specs.extend(
                CellFile::single(d, node)
                    .drives(crate::cell::Vendors::NONE)
                    .expect("known device"),
            );
        }
        let mut cell = SlaveChain::new(specs).expect("chain");
        cell.boot(Instant::from_nanos(0));
        CellLink {
            cell,
            now_ns: 0,
            sent: Vec::new(),
        }
    }
}

impl FrameLink for CellLink {
    async fn round_trip(
        &mut self,
        frame: &mut [u8],
        index: u8,
        _timeout: Duration,
    ) -> io::Result<bool> {
        self.sent.push(frame.to_vec());
        self.now_ns += 100_000;
        let now = Instant::from_nanos(self.now_ns);
        let forwarded = self.cell.on_frame(now, frame).forward();
        self.cell.poll(now);
        Ok(forwarded && reply_datagram(frame, index).is_some())
    }
}

fn master(devices: &[&str]) -> EcatMaster<CellLink> {
    EcatMaster::new(CellLink::new(devices))
}

const T: Duration = Duration::from_secs(1);

fn first_datagram(frame: &[u8]) -> Datagram<Vec<u8>> {
    let ecat = Frame::new_checked(&frame[frame::ETHERNET_HEADER_LEN..]).expect("frame");
    let dg = ecat.datagrams().next().expect("one").expect("whole");
    Datagram::new_unchecked(dg.into_inner().to_vec())
}

#[tokio::test]
async fn attach_counts_with_brd_and_addresses_by_position() {
    let mut m = master(&["cmmp-as", "cmmp-as"]);
    assert_eq!(m.attach().await.expect("attach"), 2);
    let sent = &m.link_mut().sent;
    assert_eq!(sent.len(), 3);
    let brd = first_datagram(&sent[0]);
    assert_eq!(
        (brd.command(), brd.ado(), brd.data_len()),
        (Command::Brd, 0x0000, 2)
    );
    for (k, (adp, station)) in [(0x0000u16, 0x1001u16), (0xFFFF, 0x1002)]
        .iter()
        .enumerate()
    {
        let d = first_datagram(&sent[k + 1]);
        assert_eq!(d.command(), Command::Apwr);
        assert_eq!((d.adp(), d.ado()), (*adp, 0x0010));
        assert_eq!(d.data(), station.to_le_bytes());
        // The source MAC is SOEM's; the twin marks the reply, not the request.
        assert_eq!(&sent[k + 1][6..12], &[1; 6]);
    }
    for i in 0..2 {
        let esc = m.link_mut().cell.esc(i).expect("slave");
        assert_eq!(esc.station_address(), 0x1001 + i as u16);
    }
}

#[tokio::test]
async fn scan_reads_identity_and_name_from_the_sii() {
    let mut m = master(&["cmmp-as", "cmmp-as"]);
    let n = m.attach().await.expect("attach");
    for slave in 1..=n {
        let info = m.slave_info(slave).await.expect("info");
        assert_eq!(info.station, 0x1000 + slave);
        assert_eq!(info.identity.vendor_id, 0x1D, "Festo");
        assert_eq!(info.identity.product_code, devices::CMMP_AS.product_code);
        assert_eq!(info.identity.revision, devices::CMMP_AS.revision);
        assert!(
            info.name
                .as_deref()
                .is_some_and(|s| s.starts_with("CMMP-AS")),
            "{info:?}"
        );
        assert_eq!(info.al.state(), Some(AlState::Init));
        assert!(!info.al.error());
    }
    // An EEPROM offered to the PDI (as SOEM leaves it) is offered back after a read.
    m.write(1, 0x0500, &[0x01]).await.expect("to PDI");
    m.read_sii(1).await.expect("SII");
    assert_eq!(m.read(1, 0x0500, 1).await.expect("0x0500"), [0x01]);
    // A slave that is not there.
    assert!(matches!(
        m.read(3, 0x0130, 2).await,
        Err(EcatError::WorkingCounter { wkc: 0, .. })
    ));
}

#[tokio::test]
async fn state_ladder_and_refusals() {
    let mut m = master(&["cmmp-as"]);
    m.attach().await.expect("attach");
    // Skipping states is refused with 0x0011 and leaves the error bit.
    match m.request_state(1, AlState::Op, T, T).await {
        Err(EcatError::Refused {
            from: AlState::Init,
            requested: AlState::Op,
            state: Some(AlState::Init),
            code,
            ..
        }) => assert_eq!(code, AlStatusCode::INVALID_REQUESTED_STATE_CHANGE),
        other => panic!("refusal expected: {other:?}"),
    }
    let st = m.al_status(1).await.expect("status");
    assert!(st.error());
    // Asked again, the same refusal: the unchanged error status is not taken for the old one.
    assert!(matches!(
        m.request_state(1, AlState::Op, T, T).await,
        Err(EcatError::Refused { code, .. }) if code == AlStatusCode::INVALID_REQUESTED_STATE_CHANGE
    ));
    // The next request acknowledges the error.
    for target in [AlState::PreOp, AlState::SafeOp, AlState::Op] {
        let c = m.request_state(1, target, T, T).await.expect("step up");
        assert_eq!(c.to.state(), Some(target));
        assert!(!c.to.error());
    }
    let esc = m.link_mut().cell.esc(0).expect("slave");
    let sm2 = esc.sync_manager(2).expect("SM2");
    let sm3 = esc.sync_manager(3).expect("SM3");
    // CMMP-AS default mapping: controlword out, statusword in (2 bytes each).
    assert_eq!((sm2.start, sm2.length, sm2.control), (0x1100, 2, 0x64));
    assert_eq!((sm3.start, sm3.length, sm3.control), (0x1180, 2, 0x20));
    let f0 = esc.fmmu(0).expect("FMMU0");
    assert!(f0.enable && f0.write_enable && f0.physical_start == 0x1100);
    let f1 = esc.fmmu(1).expect("FMMU1");
    assert!(f1.enable && f1.read_enable && f1.logical_start == f0.logical_start + 2);
    // Op holds without cyclic data: the watchdog is off.
    for _ in 0..20 {
        m.link_mut().cell.poll(Instant::from_nanos(10_000_000_000));
    }
    assert_eq!(
        m.al_status(1).await.expect("status").state(),
        Some(AlState::Op)
    );
    // Asking for the state it is in changes nothing.
    let c = m.request_state(1, AlState::Op, T, T).await.expect("stay");
    assert_eq!(c.from, c.to);
    let c = m.request_state(1, AlState::Init, T, T).await.expect("down");
    assert_eq!(c.to.state(), Some(AlState::Init));
    // And up again: the mailbox is configured again from the SII.
    m.request_state(1, AlState::PreOp, T, T)
        .await
        .expect("pre-op again");
}

#[tokio::test]
async fn safe_op_from_init_is_refused_without_set_up() {
    let mut m = master(&["cmmp-as"]);
    m.attach().await.expect("attach");
    let e = m.request_state(1, AlState::SafeOp, T, T).await;
    assert!(
        matches!(e, Err(EcatError::Refused { code, .. }) if code == AlStatusCode::INVALID_REQUESTED_STATE_CHANGE),
        "{e:?}"
    );
    let text = e.err().map(|e| e.to_string()).unwrap_or_default();
    assert!(text.contains("INIT -> SAFEOP refused"), "{text}");
    assert!(
        text.contains("0x0011: Invalid requested state change"),
        "{text}"
    );
}

#[tokio::test]
async fn sdo_read_write_and_abort_in_pre_op() {
    let mut m = master(&["cmmp-as"]);
    m.attach().await.expect("attach");
    assert!(matches!(
        m.sdo_upload(1, 0x1018, 1, T).await,
        Err(EcatError::NoMailbox {
            state: Some(AlState::Init),
            ..
        })
    ));
    m.request_state(1, AlState::PreOp, T, T)
        .await
        .expect("pre-op");
    assert_eq!(
        m.sdo_upload(1, 0x1018, 1, T).await.expect("vendor"),
        [0x1D, 0, 0, 0]
    );
    m.sdo_download(1, 0x6065, 0, &12345u32.to_le_bytes(), T)
        .await
        .expect("write");
    assert_eq!(
        m.sdo_upload(1, 0x6065, 0, T).await.expect("read back"),
        12345u32.to_le_bytes()
    );
    match m.sdo_upload(1, 0x5FFF, 0, T).await {
        Err(EcatError::Abort { code, index, .. }) => {
            assert_eq!((code, index), (AbortCode::NO_OBJECT, 0x5FFF))
        }
        other => panic!("abort expected: {other:?}"),
    }
    // Hidden under CoE (CMMP-AS Tab. 4.9): 1008h answers 0602 0000h.
    let e = m.sdo_upload(1, 0x1008, 0, T).await.expect_err("hidden");
    assert!(
        e.to_string().contains("0x06020000 (Object does not exist"),
        "{e}"
    );
    // The drive's process-data sizes as config_map computes them.
    assert_eq!(m.pdo_bytes(1, 0x1C12, T).await.expect("1C12"), Some(2));
    assert_eq!(m.pdo_bytes(1, 0x1C13, T).await.expect("1C13"), Some(2));
}

/// A second master process starts its mailbox counter over; its first request carries
/// counter 0 so the slave does not take it for a repetition of the last one it saw.
#[tokio::test]
async fn a_new_master_is_not_taken_for_a_repetition() {
    let mut m = master(&["cmmp-as"]);
    m.attach().await.expect("attach");
    m.request_state(1, AlState::PreOp, T, T)
        .await
        .expect("pre-op");
    // One request: a master counting from 1 would end on 1 and start on 1 again.
    m.sdo_upload(1, 0x1018, 1, T).await.expect("first run");
    let link = std::mem::replace(m.link_mut(), CellLink::new(&["cmmp-as"]));
    let mut again = EcatMaster::new(link);
    again.attach().await.expect("attach");
    again
        .sdo_upload(1, 0x1018, 1, T)
        .await
        .expect("second run, counter 0");
    again
        .sdo_upload(1, 0x1018, 2, T)
        .await
        .expect("second run, counter 1 again");
    assert_eq!(
        again
            .link_mut()
            .cell
            .device(0)
            .expect("dev")
            .coe_counters()
            .duplicates,
        0
    );
}

#[tokio::test]
async fn no_reply_is_an_error_after_retries() {
    struct Deaf(u32);
    impl FrameLink for Deaf {
        async fn round_trip(&mut self, _: &mut [u8], _: u8, _: Duration) -> io::Result<bool> {
            self.0 += 1;
            Ok(false)
        }
    }
    let mut m = EcatMaster::new(Deaf(0));
    assert!(matches!(m.count_slaves().await, Err(EcatError::NoReply(_))));
    assert_eq!(m.link_mut().0, 3, "sent, then retried twice");
}

/// One ESC with the CoE server of the test bench personality (every data type, a 4 KiB
/// string): the twin's chain builds CiA 402 slaves only, this one is wired by hand.
struct BenchLink {
    esc: ethercat::Esc<'static>,
    coe: Box<ethercat::coe::CoeServer>,
    od: od::ObjectDictionary<Vec<u8>>,
    now_ns: u64,
}

impl BenchLink {
    fn new() -> Self {
        let desc = &devices::TESTBENCH;
        let cfg = ethercat::sii::SiiConfig {
            rx_assigned: &[],
            tx_assigned: &[],
            ..ethercat::sii::SiiConfig::from_description(&devices::CMMP_AS)
        };
        let mut image = vec![0u8; ethercat::sii::DEFAULT_IMAGE_SIZE];
        ethercat::sii::build_sii(desc, &cfg, &mut image).expect("bench SII");
        BenchLink {
            esc: ethercat::Esc::with_sii(Box::leak(image.into_boxed_slice())),
            coe: Box::new(ethercat::coe::CoeServer::new(
                desc,
                ethercat::coe::CoeConfig::FULL,
            )),
            od: od::ObjectDictionary::new(desc, 1, vec![0u8; desc.storage_size]).expect("od"),
            now_ns: 0,
        }
    }
}

impl FrameLink for BenchLink {
    async fn round_trip(
        &mut self,
        frame: &mut [u8],
        index: u8,
        _timeout: Duration,
    ) -> io::Result<bool> {
        self.now_ns += 100_000;
        let forwarded = self
            .esc
            .process(Instant::from_nanos(self.now_ns), frame)
            .forward();
        ethercat::coe::pump(&mut self.esc, &mut self.coe, &mut self.od);
        Ok(forwarded && reply_datagram(frame, index).is_some())
    }
}

/// A 300-byte string goes down with a normal initiate plus a segment and comes back through
/// a segmented upload (128-byte mailboxes).
#[tokio::test]
async fn segmented_transfers_of_a_long_string() {
    let mut m = EcatMaster::new(BenchLink::new());
    assert_eq!(m.attach().await.expect("attach"), 1);
    let info = m.slave_info(1).await.expect("info");
    assert_eq!(info.identity.vendor_id, devices::TESTBENCH.vendor_id);
    m.request_state(1, AlState::PreOp, T, T)
        .await
        .expect("pre-op");
    let text: Vec<u8> = (0..300u32).map(|i| b'A' + (i % 26) as u8).collect();
    m.sdo_download(1, 0x2001, 0, &text, T)
        .await
        .expect("segmented write");
    assert_eq!(
        m.sdo_upload(1, 0x2001, 0, T).await.expect("segmented read"),
        text
    );
    // Without 1C12h the process-data size is unknown over CoE.
    assert_eq!(m.pdo_bytes(1, 0x1C12, T).await.expect("no 1C12"), None);
}
