//! Ethernet frames into a chain of two CMMP-AS EtherCAT slaves (ESC registers, SII, AL state
//! machine, mailbox with CoE, process data, distributed clocks), with time passing between
//! them: no panic, a processed frame keeps its length, and the chain's deadline moves on.
#![no_main]

use drivetwin::cell::config::CellFile;
use drivetwin::ecat::chain::SlaveChain;
use libfuzzer_sys::arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;
use od::Instant;

fn cell() -> Option<SlaveChain> {
    let mut specs = CellFile::single("cmmp-as", 1).drives(drivetwin::vendors::VENDORS.runtime).ok()?;
    specs.extend(CellFile::single("cmmp-as", 2).drives(drivetwin::vendors::VENDORS.runtime).ok()?);
    SlaveChain::new(specs).ok()
}

fn run(u: &mut Unstructured) -> Result<()> {
    let Some(mut chain) = cell() else {
        return Ok(());
    };
    let mut now = Instant::from_millis(1);
    chain.boot(now);
    while !u.is_empty() {
        if u.ratio(1u8, 5)? {
            let until = now.as_nanos() + u.int_in_range(0u64..=5_000_000)?;
            let mut polls = 0u32;
            while let Some(t) = chain.deadline().filter(|t| t.as_nanos() <= until) {
                polls += 1;
                // A deadline that stays, or creeps on by nanoseconds (crash-2ad63ffb: a SYNC0
                // grid of nanoseconds), would make the runtime spin.
                assert!(polls < 100_000, "100 000 polls in one pause, the last at {t:?}");
                now = t.max(now);
                chain.poll(now);
            }
            now = Instant::from_nanos(until);
            continue;
        }
        let len = u.int_in_range(0usize..=1514)?.min(u.len());
        let mut frame = u.bytes(len)?.to_vec();
        // Mostly an EtherCAT frame (EtherType 88A4h, type 1), so the datagrams are reached.
        if frame.len() >= 16 && u.ratio(3u8, 4)? {
            frame[12] = 0x88;
            frame[13] = 0xA4;
            frame[15] = (frame[15] & 0x07) | 0x10;
        }
        let before = frame.len();
        chain.on_frame(now, &mut frame);
        assert_eq!(frame.len(), before, "frames are processed in place");
    }
    Ok(())
}

fuzz_target!(|data: &[u8]| {
    let _ = run(&mut Unstructured::new(data));
});
