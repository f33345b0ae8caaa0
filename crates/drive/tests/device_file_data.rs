//! The holding brake's delays and the plant supervision's messages are the device file's
//! (`[device.brake]`, `[device.plant]`), not the vendor's: the CMMP-AS vendor on its own file
//! with other keys in those tables waits and raises what the keys say.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::time::Duration;

use drive::device_control::State;
use drive::drive::{Drive, DriveSettings};
use drive::encoder_fault::EncoderFault;
use drive::vendors::festo_cmmp_as::CmmpAs;
use od::{DeviceDescription, Instant, ObjectAccess, ObjectDictionary};

/// `devices/cmmp-as.toml` with the table `[device.<table>]` replaced by `keys`, built as the
/// program builds a file it reads at run time.
fn cmmp_as_with(table: &str, keys: &str) -> &'static DeviceDescription {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../devices/cmmp-as.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let head = format!("[device.{table}]\n");
    let start = text.find(&head).expect("the table") + head.len();
    let end = start
        + text[start..]
            .find("\n\n")
            .expect("a blank line after the table");
    let edited = format!("{}{keys}{}", &text[..start], &text[end..]);
    devdesc::runtime::leak(&devdesc::parse(&edited, "cmmp-as.toml").unwrap())
}

struct Rig {
    d: Drive<Vec<u8>, CmmpAs>,
    now: Instant,
}

impl Rig {
    fn new(desc: &'static DeviceDescription) -> Rig {
        let od = ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]).unwrap();
        let settings = DriveSettings {
            mode_change_time: Duration::from_millis(2),
            ..DriveSettings::default()
        };
        let mut r = Rig {
            d: Drive::new(od, settings),
            now: Instant::ZERO,
        };
        r.run_ms(1);
        r
    }
    fn run_ms(&mut self, ms: u64) {
        self.now = self.now + Duration::from_millis(ms);
        self.d.step(self.now);
    }
    fn cw(&mut self, v: u16) {
        self.d.write(0x6040, 0, &v.to_le_bytes()).unwrap();
        self.run_ms(2);
    }
    fn enable(&mut self) {
        self.cw(0x06);
        self.cw(0x07);
        self.cw(0x0F);
    }
    fn brake_closed(&self) -> bool {
        self.d.axis().motor().brake()
    }
}

/// §5.16 opens the brake with the output stage; a file whose `release` names 6510h:18 opens
/// it that delay later, with the same vendor.
#[test]
fn the_brake_waits_what_the_device_file_names() {
    let delay_50_ms = |r: &mut Rig| r.d.write(0x6510, 0x18, &50u16.to_le_bytes()).unwrap();
    let mut file = Rig::new(&devices::CMMP_AS);
    delay_50_ms(&mut file);
    file.enable();
    assert!(!file.brake_closed(), "the CMMP-AS's file: open at once");
    let later = cmmp_as_with(
        "brake",
        "release = [[0x6510, 0x18]]\nmotion = [[0x6510, 0x18]]\nengage = [[0x6510, 0x18]]",
    );
    assert_eq!(later.brake.release, [(0x6510, 0x18)]);
    let mut r = Rig::new(later);
    delay_50_ms(&mut r);
    r.enable();
    assert!(r.brake_closed(), "closed right after the enable");
    r.run_ms(40);
    assert!(r.brake_closed(), "closed before 6510h:18 has passed");
    r.run_ms(10);
    assert!(!r.brake_closed(), "open once 6510h:18 has passed");
}

/// App. B.3 raises 08-0 for a pulled encoder cable; a file whose `[device.plant]` names no
/// encoder message raises nothing for it, with the same vendor.
#[test]
fn the_plant_supervision_raises_what_the_device_file_names() {
    let pulled = |r: &mut Rig| {
        r.enable();
        r.run_ms(50);
        r.d.set_encoder_fault(EncoderFault::Disconnected);
        r.run_ms(200);
    };
    let mut file = Rig::new(&devices::CMMP_AS);
    pulled(&mut file);
    assert!(file.d.errors().contains(&0x7380), "{:?}", file.d.errors());
    assert_eq!(file.d.state(), State::Fault);
    let without = cmmp_as_with(
        "plant",
        "motor_warning = \"18-0\"\nmotor_over = \"03-0\"\nstage_over = \"04-0\"",
    );
    assert_eq!(without.plant.encoder_lost, None);
    let mut r = Rig::new(without);
    pulled(&mut r);
    assert!(!r.d.errors().contains(&0x7380), "{:?}", r.d.errors());
    assert_eq!(r.d.state(), State::OperationEnabled);
}
