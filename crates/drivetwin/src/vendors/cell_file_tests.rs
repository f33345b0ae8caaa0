//! The cell file's tests with the devices' sections of [`super::CELL_SECTIONS`]: travel,
//! CMMO-ST, the examples, switches, bus rates, the keys of each device.

use super::{CELL_SECTIONS, VENDORS};
use crate::cell::bus_rate::{self, BitrateSetting, BusRate};
use crate::cell::config::*;
use drive::stepper::{StepperData, StepperMode};
use drive::travel::TravelSettings;
use std::path::{Path, PathBuf};

mod travel_tests {
    use super::*;

    fn spec(text: &str) -> Result<Vec<DriveSpec>, ConfigError> {
        let file: CellFile = toml::from_str(text).map_err(|source| ConfigError::Toml {
            path: PathBuf::from("cell.toml"),
            source,
        })?;
        file.drives(VENDORS.runtime)
    }

    #[test]
    fn drive_travel_overrides_the_defaults() {
        let drives = spec(
            "[[drive]]\ndevice = \"cmmp-as\"\n[drive.travel]\nnegative_limit = -100000\n\
             home_switch_low = 1000\nindex_phase = 0\nhoming_max_distance = 0\n",
        )
        .unwrap();
        let s = drives[0].settings.unwrap();
        assert_eq!(s.travel.negative_limit, Some(-100_000));
        assert_eq!(
            s.travel.home_switch.map(|h| (h.low, h.high)),
            Some((1000, 90_000))
        );
        assert_eq!(s.travel.index_phase, Some(0));
        assert_eq!(
            s.travel.positive_stop,
            TravelSettings::default().positive_stop
        );
        assert_eq!(s.homing_max_distance, 0);
    }

    #[test]
    fn a_travel_out_of_order_is_refused() {
        for bad in [
            "negative_limit = -2000000",
            "home_switch_low = 100000",
            "index_phase = 65536",
            "positive_stop = 1099511627777",
        ] {
            let text = format!("[[drive]]\ndevice = \"cmmp-as\"\n[drive.travel]\n{bad}\n");
            let err = spec(&text).unwrap_err().to_string();
            assert!(err.contains("travel"), "{bad}: {err}");
        }
    }
}

mod cmmo_st_tests {
    use super::*;

    fn spec(text: &str) -> Result<Vec<DriveSpec>, String> {
        let file: CellFile = toml::from_str(text).map_err(|e| e.to_string())?;
        file.drives(VENDORS.runtime).map_err(|e| e.to_string())
    }

    #[test]
    fn stepper_axis_and_modbus_of_a_cmmo_st() {
        let drives = spec(
            "[[drive]]\ndevice = \"cmmo-st\"\nmodbus = \"127.0.0.1:1600\"\n\
             modbus_timeout_ms = 200\n[drive.stepper]\nmode = \"open-loop\"\n\
             load_torque = -0.1\nholding_torque = 1.2\n[drive.axis]\nend_stops = \"none\"\n\
             reference_switch = [1.0, 1.25]\nindex_pulse = 0.5\n[drive.objects]\n\
             \"2079:01\" = 65\n",
        )
        .unwrap();
        let f = drives[0].fhpp.as_ref().expect("an FHPP drive");
        assert_eq!(f.modbus.as_deref(), Some("127.0.0.1:1600"));
        assert_eq!(f.watchdog_ms, Some(200));
        assert_eq!(f.settings.mode, StepperMode::OpenLoop);
        assert_eq!(f.settings.stepper.load_torque, -0.1);
        assert_eq!(f.settings.stepper.holding_torque, 1.2);
        let d = StepperData::default();
        assert_eq!(f.settings.stepper.rotor_inertia, d.rotor_inertia);
        assert_eq!(f.settings.mechanics.end_stops, None, "an endless axis");
        assert_eq!(f.settings.mechanics.reference_switch, Some((1.0, 1.25)));
        assert_eq!(f.settings.mechanics.index_pulse, Some(0.5));
        assert_eq!(drives[0].commissioning.len(), 1, "PNU 121:1 commissioned");
        assert!(drives[0].settings.is_none(), "no CiA 402 model");
    }

    #[test]
    fn the_defaults_of_a_cmmo_st() {
        let drives = spec("[[drive]]\ndevice = \"cmmo-st\"\n").unwrap();
        let f = drives[0].fhpp.as_ref().expect("an FHPP drive");
        assert_eq!(f.modbus, None);
        assert_eq!(f.settings.mode, StepperMode::ClosedLoop);
        assert_eq!(f.settings.mechanics, Default::default());
        // A CMMO-ST and a CMMP-AS may both say node 1: only CAN drives share a bus.
        let both = spec("[[drive]]\ndevice = \"cmmp-as\"\n[[drive]]\ndevice = \"cmmo-st\"\n");
        assert_eq!(both.map(|d| d.len()), Ok(2));
    }

    #[test]
    fn wrong_sections_and_values_are_refused_with_their_name() {
        let cases = [
            (
                "device = \"cmmp-as\"\n[drive.stepper]\nmode = \"open-loop\"",
                "CMMO-ST",
            ),
            ("device = \"cmmp-as\"\nmodbus = \"127.0.0.1:1\"", "CMMO-ST"),
            (
                "device = \"cmmo-st\"\n[drive.motor]\ninertia = 1.0",
                "[drive.stepper]",
            ),
            (
                "device = \"cmmo-st\"\n[drive.axis]\nend_stops = [2.0, 1.0]",
                "low ≤ high",
            ),
            (
                "device = \"cmmo-st\"\n[drive.axis]\nend_stops = [1.0, 1.0]",
                "apart",
            ),
            (
                "device = \"cmmo-st\"\n[drive.axis]\nindex_pulse = 1.5",
                "0 … 1",
            ),
            (
                "device = \"cmmo-st\"\n[drive.axis]\nreference_switch = \"no\"",
                "\"none\"",
            ),
            (
                "device = \"cmmo-st\"\n[drive.stepper]\nholding_torque = 0.0",
                "> 0",
            ),
            (
                "device = \"cmmo-st\"\n[drive.stepper]\nload_inertia = -1.0",
                "≥ 0",
            ),
            (
                "device = \"cmmo-st\"\n[drive.stepper]\nmode = \"servo\"",
                "unknown variant",
            ),
            (
                "device = \"cmmo-st\"\n[drive.stepper]\nteeth = 50",
                "unknown field",
            ),
        ];
        for (text, expected) in cases {
            let err = spec(&format!("[[drive]]\n{text}\n")).expect_err(text);
            assert!(err.contains(expected), "{text}: {err}");
        }
    }
}

mod example_tests {
    use super::*;

    /// Every cell file under `examples/` loads and describes its drives.
    #[test]
    fn the_example_cell_files_load() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
        let mut seen = 0;
        for entry in std::fs::read_dir(&dir).expect("examples/") {
            let path = entry.expect("entry").path();
            if path.extension().is_some_and(|e| e == "toml") {
                let file = CellFile::load(&path).unwrap_or_else(|e| panic!("{e}"));
                let drives = file
                    .drives(VENDORS.runtime)
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                assert!(!drives.is_empty(), "{}", path.display());
                // Its buses' rates: named, or the nodes agree.
                file.bus_rates(&drives)
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                seen += 1;
            }
        }
        assert!(seen >= 2, "examples/cell.toml and examples/machine.toml");
    }
}

mod switches_tests {
    use super::*;

    fn nanotec(device: &str, section: &str) -> Result<DriveSpec, ConfigError> {
        spec(&format!(
            "[[drive]]\ndevice = \"{device}\"\nnode = 9\n{section}\n"
        ))
        .map(|mut v| v.remove(0))
    }

    /// NT-NODE-07 from a cell file: switches = node + 128 with no bit-rate code in 2005h: the
    /// drive is built without enables, so it never leaves Switch On Disabled; with a code it
    /// is a normal drive.
    #[test]
    fn nt_node_07_no_bit_rate_code_keeps_the_drive_from_moving() {
        let d = nanotec(
            "nanotec-smci47s",
            "[drive.rotary_switches]\nleft = 5\nright = 8\n[drive.objects]\n\"2005:00\" = 0",
        )
        .unwrap();
        assert_eq!(d.node, 5);
        assert!(!d.settings.expect("a drive").enables_present);
        let d = nanotec(
            "nanotec-smci47s",
            "[drive.rotary_switches]\nleft = 5\nright = 8\n[drive.objects]\n\"2005:00\" = 134",
        )
        .unwrap();
        assert!(d.settings.expect("a drive").enables_present);
    }

    /// `motor_type`: a BLDC connected (the DB57-like default), 2004h:07 and Appendix 18.2's
    /// load-angle curve as commissioning values, `[drive.objects]` after them (so they win);
    /// `stepper` sets 2004h:07 = 0 only; a drive without 2004h:07 refuses the key.
    #[test]
    fn nanotec_motor_type_sets_2004h_07_and_the_bldc() {
        let value = |d: &DriveSpec, index: u16, sub: u8| -> Vec<Vec<u8>> {
            d.commissioning
                .iter()
                .filter(|c| (c.index, c.sub) == (index, sub))
                .map(|c| c.bytes.clone())
                .collect()
        };
        for (name, code) in [
            ("bldc-hall", 1u8),
            ("bldc-hall-encoder", 2),
            ("bldc-encoder", 2),
        ] {
            let d = nanotec("nanotec-smci47s", &format!("motor_type = \"{name}\"")).unwrap();
            assert_eq!(value(&d, 0x2004, 7), vec![vec![code]], "{name}");
            assert_eq!(value(&d, 0x200C, 2), vec![16500u16.to_le_bytes().to_vec()]);
            assert_eq!(value(&d, 0x200C, 7), vec![19000u16.to_le_bytes().to_vec()]);
            assert!(d.settings.expect("a drive").bldc.is_some(), "{name}");
        }
        let d = nanotec("nanotec-pd4n", "motor_type = \"stepper\"").unwrap();
        assert_eq!(value(&d, 0x2004, 7), vec![vec![0]]);
        assert!(value(&d, 0x200C, 1).is_empty());
        assert!(d.settings.expect("a drive").bldc.is_none());
        let d = nanotec(
            "nanotec-pd4n",
            "motor_type = \"bldc-hall\"\n[drive.objects]\n\"200C:02\" = 16000",
        )
        .unwrap();
        assert_eq!(
            value(&d, 0x200C, 2).last(),
            Some(&16000u16.to_le_bytes().to_vec()),
            "[drive.objects] comes last"
        );
        for (device, bad, says) in [
            ("cmmp-as", "motor_type = \"bldc-hall\"", "2004h:07"),
            ("cmmo-st", "motor_type = \"stepper\"", "2004h:07"),
            ("nanotec-pd4n", "motor_type = \"servo\"", "unknown variant"),
        ] {
            let err = nanotec(device, bad).unwrap_err().to_string();
            assert!(err.contains(says), "{device} {bad}: {err}");
        }
    }

    /// NT-NODE-01 from a cell file: SMCI47-S left = 1, right = 2 → node 33 (over `node`), and
    /// 2009h reads 33 (NT-NODE-09); switches 0 → 2009h of [drive.objects] (NT-NODE-02); PD4-N
    /// switch 9 → node 9 − 8 = 1 (NT-NODE-04).
    #[test]
    fn nanotec_rotary_switches_give_the_node_id() {
        let d = nanotec(
            "nanotec-smci47s",
            "[drive.rotary_switches]\nleft = 1\nright = 2",
        )
        .unwrap();
        assert_eq!(d.node, 33);
        assert!(d
            .commissioning
            .iter()
            .any(|c| (c.index, c.sub, c.bytes.as_slice()) == (0x2009, 0, &[33][..])));
        let d = nanotec(
            "nanotec-smci47s",
            "[drive.rotary_switches]\nleft = 0\nright = 0\n[drive.objects]\n\"2009:00\" = 42",
        )
        .unwrap();
        assert_eq!(d.node, 42);
        let d = nanotec("nanotec-pd4n", "[drive.rotary_switches]\nswitch = 9").unwrap();
        assert_eq!(d.node, 1);
        for (device, bad, says) in [
            ("nanotec-pd4n", "left = 1", "one switch"),
            ("nanotec-smci47s", "switch = 1", "two switches"),
            ("nanotec-smci47s", "left = 16", "0…15"),
            ("cmmp-as", "left = 1", "no rotary switches"),
        ] {
            let err = nanotec(device, &format!("[drive.rotary_switches]\n{bad}"))
                .unwrap_err()
                .to_string();
            assert!(err.contains(says), "{device} {bad}: {err}");
        }
    }

    fn spec(text: &str) -> Result<Vec<DriveSpec>, ConfigError> {
        let file: CellFile = toml::from_str(text).map_err(|source| ConfigError::Toml {
            path: PathBuf::from("cell.toml"),
            source,
        })?;
        file.drives(VENDORS.runtime)
    }

    fn drive(switches: &str) -> Result<DriveSpec, ConfigError> {
        spec(&format!(
            "[[drive]]\ndevice = \"cmmp-as\"\nnode = 9\n[drive.switches]\n{switches}\n"
        ))
        .map(|mut v| v.remove(0))
    }

    /// CMMP-NODE-01, CMMP-NODE-05, CMMP-NODE-08 from a cell file: DIP 1, 2, 4, 5 ON → node 27
    /// (over the file's `node`), DIP6 ON → 250 kbit/s, DIP8 ON → on the bus.
    #[test]
    fn m3_dip_switches_give_node_bit_rate_and_activation() {
        let d = drive("variant = \"m3\"\non = [1, 2, 4, 5, 6, 8]").unwrap();
        assert_eq!(d.node, 27);
        let f = d.fieldbus.unwrap();
        assert_eq!((f.bit_rate_kbit, f.can_active), (250, true));
        assert!(d.on_can().unwrap());
        // CMMP-NODE-08: DIP8 OFF → CANopen deactivated; CMMP-NODE-02: all offsets OFF → 1.
        let off = drive("variant = \"m3\"\non = []").unwrap();
        assert_eq!(off.node, 1);
        assert!(!off.on_can().unwrap());
        // CMMP-NODE-03: base 120 + 27 → 127.
        let d = drive("variant = \"m3\"\nbase_address = 120\non = [1, 2, 4, 5, 8]").unwrap();
        assert_eq!(d.node, 127);
    }

    /// CMMP-NODE-04, CMMP-NODE-06, CMMP-NODE-07 from a cell file: M0 DIN0, 1, 3 HIGH → node
    /// 11; DIN13 → 500 kbit/s; DIN8 HIGH → on the bus; DIN9 HIGH (FHPP) is refused.
    #[test]
    fn m0_inputs_give_node_bit_rate_and_activation() {
        let d = drive("variant = \"m0\"\non = [0, 1, 3, 8, 13]").unwrap();
        assert_eq!(d.node, 11);
        assert_eq!(d.fieldbus.unwrap().bit_rate_kbit, 500);
        assert!(d.on_can().unwrap());
        let fhpp = drive("variant = \"m0\"\non = [8, 9]").unwrap();
        assert!(matches!(fhpp.on_can(), Err(ConfigError::FhppOverCan(1))));
        let fct =
            drive("variant = \"m0\"\nvia_din = false\nbase_address = 4\non = [0, 1]").unwrap();
        assert_eq!(fct.node, 4);
        assert!(fct.on_can().unwrap(), "FCT activates CAN");
    }

    #[test]
    fn bad_switches_are_clear_errors() {
        for (bad, says) in [
            ("variant = \"m3\"\non = [9]", "DIP 9"),
            ("variant = \"m3\"\non = [0]", "DIP 0"),
            ("variant = \"m0\"\non = [5]", "DIN5"),
            ("variant = \"m0\"\nfct_bit_rate_kbit = 800", "800"),
        ] {
            let err = drive(bad).unwrap_err().to_string();
            assert!(
                err.contains(says) && err.contains("switches"),
                "{bad}: {err}"
            );
        }
        assert!(drive("variant = \"m5\"").is_err());
        let err = spec("[[drive]]\ndevice = \"testbench\"\n[drive.switches]\nvariant = \"m3\"\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("no CMMP-AS switches"), "{err}");
        // Two drives whose switches give the same node.
        let err = spec(
            "[[drive]]\ndevice = \"cmmp-as\"\n[drive.switches]\nvariant = \"m3\"\non = [1]\n\
             [[drive]]\ndevice = \"cmmp-as\"\nnode = 2\n[drive.switches]\nvariant = \"m3\"\n",
        )
        .unwrap_err();
        assert!(matches!(err, ConfigError::DuplicateNode(1)), "{err}");
    }
}

mod bus_rate_tests {
    use super::*;

    fn file(text: &str) -> CellFile {
        toml::from_str(text).unwrap_or_else(|e| panic!("{e}"))
    }

    fn rates(text: &str) -> Result<Vec<BusRate>, ConfigError> {
        let f = file(text);
        f.bus_rates(&f.drives(VENDORS.runtime)?)
    }

    fn timed(bitrate: u32, from_nodes: bool) -> BusRate {
        BusRate::Timed {
            bitrate,
            from_nodes,
        }
    }

    /// The default cell runs at its CMMP-AS's 125 kbit/s; a Nanotec's at 1 Mbit/s; agreeing
    /// nodes of different personalities give the bus their rate.
    #[test]
    fn the_nodes_rate_without_a_bitrate() {
        let single = CellFile::single("cmmp-as", 1);
        assert_eq!(
            single
                .bus_rates(&single.drives(VENDORS.runtime).unwrap())
                .unwrap(),
            [timed(125_000, true)]
        );
        assert_eq!(
            rates("[[drive]]\ndevice = \"nanotec-pd4n\"\n").unwrap(),
            [timed(1_000_000, true)]
        );
        // CMMP-AS DIP6 + DIP7 (1 Mbit/s), Nanotec, Kinco 2F81h = 100: all at 1 Mbit/s.
        let agree = "[[drive]]\ndevice = \"cmmp-as\"\n[drive.switches]\nvariant = \"m3\"\n\
                     on = [6, 7, 8]\n\
                     [[drive]]\ndevice = \"nanotec-smci47s\"\nnode = 2\n\
                     [[drive]]\ndevice = \"kinco-fd3\"\nnode = 3\n[drive.objects]\n\
                     \"2F81:00\" = 100\n";
        assert_eq!(rates(agree).unwrap(), [timed(1_000_000, true)]);
        // A bus of test bench nodes (no rate of their own): 1 Mbit/s.
        assert_eq!(
            rates("[[drive]]\ndevice = \"testbench\"\n").unwrap(),
            [timed(bus_rate::WITHOUT_NODE_RATES, true)]
        );
    }

    /// Nodes at different rates and no `bitrate`: refused, naming each node's rate and key.
    /// Drives kept off the bus (DIP8 OFF) or on another bus do not count.
    #[test]
    fn disagreeing_nodes_are_refused() {
        let err = rates(
            "[[drive]]\ndevice = \"cmmp-as\"\n\
             [[drive]]\ndevice = \"nanotec-smci47s\"\nnode = 2\n\
             [drive.rotary_switches]\nleft = 2\nright = 8\n[drive.objects]\n\"2005:00\" = 133\n",
        )
        .unwrap_err();
        let text = err.to_string();
        assert!(matches!(err, ConfigError::BusRate(_)), "{text}");
        assert!(text.contains("cmmp-as node 1: 125 kbit/s"), "{text}");
        assert!(
            text.contains(
                "nanotec-smci47s node 2: 250 kbit/s, set by [drive.objects] \"2005:00\" = 133"
            ),
            "{text}"
        );
        // The CMMP-AS's CAN off: only the Nanotec counts.
        assert_eq!(
            rates(
                "[[drive]]\ndevice = \"cmmp-as\"\n[drive.switches]\nvariant = \"m3\"\n\
                 [[drive]]\ndevice = \"nanotec-smci47s\"\nnode = 2\n"
            )
            .unwrap(),
            [timed(1_000_000, true)]
        );
        // Each bus its own rate.
        let two = "[[bus]]\nname = \"a\"\n[[bus]]\nname = \"b\"\nchannel = \"vcan1\"\n\
                   [[drive]]\ndevice = \"cmmp-as\"\nbus = \"a\"\n\
                   [[drive]]\ndevice = \"nanotec-smci47s\"\nbus = \"b\"\n";
        assert_eq!(
            rates(two).unwrap(),
            [timed(125_000, true), timed(1_000_000, true)]
        );
    }

    /// A named `bitrate` wins over the nodes (a node at another rate is silent); `"instant"`
    /// and `--bitrate` (`set_bitrate`) too.
    #[test]
    fn an_explicit_bitrate_or_instant_wins() {
        let mixed = "[[drive]]\ndevice = \"cmmp-as\"\n\
                     [[drive]]\ndevice = \"kinco-fd3\"\nnode = 2\n";
        assert_eq!(
            rates(&format!("[bus]\nbitrate = 500000\n{mixed}")).unwrap(),
            [timed(500_000, false)]
        );
        assert_eq!(
            rates(&format!("[bus]\nbitrate = \"instant\"\n{mixed}")).unwrap(),
            [BusRate::Instant]
        );
        let mut f = file(mixed);
        f.set_bitrate(BitrateSetting::Instant);
        assert_eq!(
            f.bus_rates(&f.drives(VENDORS.runtime).unwrap()).unwrap(),
            [BusRate::Instant]
        );
        let err = toml::from_str::<CellFile>("[bus]\nbitrate = \"fast\"\n").unwrap_err();
        assert!(err.to_string().contains("instant"), "{err}");
    }

    /// The Kinco DIP vectors from a cell file (each named at its assertion; the switch table
    /// itself is `drive::vendors::kinco::dip_switches`): `[drive.dip_switches]` gives the FD3's
    /// station number (node-ID) over `node`; all OFF takes 2F80h:01; 128…255 and other devices
    /// are refused.
    #[test]
    fn kinco_dip_switches_give_the_station_number() {
        let fd3 = |section: &str| {
            let text = format!("[[drive]]\ndevice = \"kinco-fd3\"\nnode = 9\n{section}\n");
            file(&text).drives(VENDORS.runtime).map(|mut v| v.remove(0))
        };
        // KINCO-DIP-01: SW1 → 1.
        assert_eq!(fd3("[drive.dip_switches]\non = [1]").unwrap().node, 1);
        // KINCO-DIP-02: SW2 → 2.
        assert_eq!(fd3("[drive.dip_switches]\non = [2]").unwrap().node, 2);
        // KINCO-DIP-03: SW1 + SW2 → 3.
        assert_eq!(fd3("[drive.dip_switches]\non = [1, 2]").unwrap().node, 3);
        // KINCO-DIP-04: SW3 → 4.
        assert_eq!(fd3("[drive.dip_switches]\non = [3]").unwrap().node, 4);
        // KINCO-DIP-06: all OFF → the stored station number 2F80h:01 (default 1).
        assert_eq!(fd3("[drive.dip_switches]\non = []").unwrap().node, 1);
        assert_eq!(
            fd3("[drive.dip_switches]\n[drive.objects]\n\"2F80:01\" = 42")
                .unwrap()
                .node,
            42
        );
        // KINCO-DIP-05: all ON is station 255, RS232 / RS485 only.
        let err = fd3("[drive.dip_switches]\non = [1, 2, 3, 4, 5, 6, 7, 8]")
            .unwrap_err()
            .to_string();
        assert!(err.contains("station 255"), "{err}");
        let err = fd3("[drive.dip_switches]\non = [9]")
            .unwrap_err()
            .to_string();
        assert!(err.contains("SW9"), "{err}");
        // The switches give no bit rate: 2F81h does.
        let d = fd3("[drive.dip_switches]\non = [1]\n[drive.objects]\n\"2F81:00\" = 25").unwrap();
        assert_eq!(d.bit_rate.map(|r| r.kbit), Some(250));
        let err = file("[[drive]]\ndevice = \"kinco-cd3\"\n[drive.dip_switches]\non = [1]\n")
            .drives(VENDORS.runtime)
            .unwrap_err()
            .to_string();
        assert!(err.contains("no DIP switches"), "{err}");
    }
}

/// The keys of each device's section, and the refusal of another device's keys.
mod device_keys_tests {
    use super::super::{festo_cmmo_st, festo_cmmp_as, kinco, nanotec};
    use super::*;
    use crate::cell::config::device_keys::{section_of, sections_of};
    use crate::cell::config::drive_section::COMMON_KEYS;

    fn file(text: &str) -> Result<CellFile, String> {
        toml::from_str(text).map_err(|e| e.to_string())
    }

    fn one(device: &str, node: u8, keys: &str) -> Result<(DriveSection, DriveSpec), String> {
        let f = file(&format!(
            "[[drive]]\ndevice = \"{device}\"\nnode = {node}\n{keys}\n"
        ))?;
        let spec = f
            .drives(VENDORS.runtime)
            .map_err(|e| e.to_string())?
            .remove(0);
        Ok((f.drive[0].clone(), spec))
    }

    /// Each device takes its own keys, flat on `[[drive]]` as before, and they reach the
    /// drive.
    #[test]
    fn each_device_takes_its_own_keys() {
        let (d, s) = one(
            "cmmp-as",
            5,
            "ci_terminal = \"127.0.0.1:29540\"\nmode_change_time_ms = 2.0\n\
             [drive.switches]\nvariant = \"m3\"\non = [1, 8]\n[drive.motor]\ninertia = 2e-5\n\
             [drive.travel]\nnegative_limit = -100000",
        )
        .unwrap();
        assert_eq!(s.ports.ci_terminal.as_deref(), Some("127.0.0.1:29540"));
        assert!(d.rest.contains_key("ci_terminal"), "kept for its section");
        assert_eq!(s.node, 1, "the switches' node");
        let settings = s.settings.unwrap();
        assert_eq!(settings.motor.inertia, 2e-5);
        assert_eq!(settings.travel.negative_limit, Some(-100_000));
        assert_eq!(
            settings.mode_change_time,
            std::time::Duration::from_millis(2)
        );

        let (_, s) = one(
            "nanotec-smci47s",
            9,
            "motor_type = \"bldc-hall\"\n[drive.rotary_switches]\nleft = 3\nright = 0\n\
             [drive.motor]\ninertia = 1e-5",
        )
        .unwrap();
        assert_eq!(s.node, 3);
        assert!(s.settings.unwrap().bldc.is_some());
        let (_, s) = one("nanotec-pd4n", 9, "[drive.rotary_switches]\nswitch = 2").unwrap();
        assert_eq!(s.node, 2);

        let (_, s) = one(
            "kinco-fd3",
            9,
            "rs232 = \"/tmp/ttyA\"\nrs485 = \"/tmp/ttyB\"\n[drive.dip_switches]\non = [1, 2]\n\
             [drive.travel]\npositive_limit = 100000",
        )
        .unwrap();
        assert_eq!(
            (s.ports.rs232.as_deref(), s.ports.rs485.as_deref()),
            (Some("/tmp/ttyA"), Some("/tmp/ttyB"))
        );
        assert_eq!(s.node, 3);
        let (_, s) = one(
            "kinco-cd3",
            1,
            "rs232 = \"/tmp/ttyC\"\nmode_change_time_ms = 0",
        )
        .unwrap();
        assert_eq!(
            (s.ports.rs232.as_deref(), s.ports.rs485.as_deref()),
            (Some("/tmp/ttyC"), None)
        );

        let (_, s) = one(
            "cmmo-st",
            1,
            "modbus = \"127.0.0.1:1600\"\nmodbus_timeout_ms = 100\n[drive.stepper]\n\
             mode = \"open-loop\"\n[drive.axis]\nindex_pulse = \"none\"",
        )
        .unwrap();
        let f = s.fhpp.unwrap();
        assert_eq!(
            (f.modbus.as_deref(), f.watchdog_ms),
            (Some("127.0.0.1:1600"), Some(100))
        );
        assert_eq!(f.settings.mechanics.index_pulse, None);

        // The common keys on a device without keys of its own.
        let (d, s) = one(
            "testbench",
            7,
            "bus = \"vcan0\"\ninterfaces = [\"canopen\"]\n[drive.objects]\n\"1017:00\" = 100\n\
             [drive.thermal]\nambient_c = 30.0",
        )
        .unwrap();
        assert!(d.rest.is_empty());
        assert!(matches!(sections_of(s.desc, CELL_SECTIONS), (false, None)));
    }

    /// A key of another device is refused naming the drive, the key and the devices that have
    /// it; the file still reads (the refusal is the drive's, as its other checks are).
    #[test]
    fn a_key_of_another_device_is_refused_naming_its_devices() {
        let err = one("nanotec-pd4n", 2, "[drive.dip_switches]\non = [1]").unwrap_err();
        assert_eq!(
            err,
            "drive 2 (nanotec-pd4n): `dip_switches` is a key of the kinco-fd3, not of this \
             device: nanotec-pd4n has no DIP switches SW1…SW8 (Kinco §3.8: the FD3's)"
        );
        for (device, key, owners) in [
            ("kinco-cd3", "rs485 = \"/tmp/x\"", "of the kinco-fd3,"),
            (
                "testbench",
                "ci_terminal = \"127.0.0.1:1\"",
                "of the cmmp-as,",
            ),
            ("cmmp-as", "rs232 = \"/tmp/x\"", "kinco-cd3 and kinco-fd3"),
            (
                "cmmp-as",
                "[drive.axis]\nindex_pulse = 0.5",
                "of the cmmo-st,",
            ),
            (
                "kinco-fd3",
                "[drive.switches]\nvariant = \"m3\"",
                "of the cmmp-as,",
            ),
            (
                "cmmo-st",
                "[drive.travel]\nnegative_limit = 0",
                "and drives from an EDS",
            ),
            ("testbench", "mode_change_time_ms = 1.0", "nanotec-pd4n"),
        ] {
            let err = one(device, 4, key).unwrap_err();
            assert!(
                err.starts_with(&format!("drive 4 ({device}): `"))
                    && err.contains(owners)
                    && err.contains(&format!("not of this device: {device} has no ")),
                "{device} {key}: {err}"
            );
        }
        let f = file("[[drive]]\ndevice = \"kinco-cd3\"\n[drive.dip_switches]\n").unwrap();
        assert!(matches!(
            f.drives(VENDORS.runtime),
            Err(ConfigError::ForeignKey { node: 1, .. })
        ));
    }

    /// A key no device has is refused when the file is read, as an unknown field with the
    /// keys the drive has.
    #[test]
    fn a_key_of_no_device_is_an_unknown_field() {
        let err = one("cmmp-as", 3, "frobnicate = 1").unwrap_err();
        assert!(
            err.contains("drive 3 (cmmp-as): unknown field `frobnicate`, expected one of"),
            "{err}"
        );
        assert!(
            err.contains("`node`") && err.contains("`motor`") && err.contains("`switches`"),
            "{err}"
        );
        assert!(!err.contains("`stepper`"), "{err}");
        // A misspelt table too.
        let err = one("cmmo-st", 1, "[drive.steper]\nmode = \"open-loop\"").unwrap_err();
        assert!(err.contains("unknown field `steper`"), "{err}");
        // Within a section, serde's own refusal.
        let err = one("cmmp-as", 1, "[drive.switches]\nvariant = \"m3\"\nof = [1]").unwrap_err();
        assert!(err.contains("unknown field `of`"), "{err}");
    }

    /// A drive from its EDS has the CiA 402 keys and no vendor's.
    #[test]
    fn a_drive_from_its_eds_has_the_cia402_keys() {
        let eds = crate::cell::eds_drive::test_files::data("epos4_like.eds");
        let drive = |keys: &str| {
            let text = format!("[[drive]]\neds = {:?}\nnode = 6\n{keys}\n", eds.display());
            file(&text).and_then(|f| f.drives(VENDORS.runtime).map_err(|e| e.to_string()))
        };
        let s = drive("mode_change_time_ms = 1.0\n[drive.motor]\ninertia = 3e-5").unwrap();
        assert_eq!(s[0].settings.unwrap().motor.inertia, 3e-5);
        let err = drive("motor_type = \"stepper\"").unwrap_err();
        assert!(
            err.contains("`motor_type` is a key of the nanotec-") && err.contains("(epos4-like)"),
            "{err}"
        );
    }

    /// The names a section's struct reads, from serde's derive: what `deserialize_struct` is
    /// asked for.
    fn fields_of<T: serde::de::DeserializeOwned>() -> &'static [&'static str] {
        #[derive(Debug)]
        struct Fields(&'static [&'static str]);
        impl std::fmt::Display for Fields {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                write!(f, "{:?}", self.0)
            }
        }
        impl std::error::Error for Fields {}
        impl serde::de::Error for Fields {
            fn custom<M: std::fmt::Display>(_: M) -> Self {
                Fields(&[])
            }
        }
        struct Probe;
        impl<'de> serde::Deserializer<'de> for Probe {
            type Error = Fields;
            fn deserialize_any<V: serde::de::Visitor<'de>>(self, _: V) -> Result<V::Value, Fields> {
                Err(Fields(&[]))
            }
            fn deserialize_struct<V: serde::de::Visitor<'de>>(
                self,
                _: &'static str,
                fields: &'static [&'static str],
                _: V,
            ) -> Result<V::Value, Fields> {
                Err(Fields(fields))
            }
            serde::forward_to_deserialize_any! {
                bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes
                byte_buf option unit unit_struct newtype_struct seq tuple tuple_struct map enum
                identifier ignored_any
            }
        }
        match T::deserialize(Probe) {
            Err(Fields(f)) => f,
            Ok(_) => &[],
        }
    }

    fn names(keys: &[device_keys::Key]) -> Vec<&'static str> {
        keys.iter().map(|k| k.name).collect()
    }

    /// Each section's table of keys is its struct's fields, no key is in two sections of one
    /// device, and every built-in CiA 402 or FHPP device has its section.
    #[test]
    fn the_tables_of_keys_are_the_sections() {
        assert_eq!(names(&cia402::KEYS), fields_of::<Cia402Keys>());
        use festo_cmmo_st::cell_section::CmmoStKeys;
        use festo_cmmp_as::cell_section::CmmpAsKeys;
        use kinco::cell_section::{KincoCd3Keys, KincoFd3Keys};
        use nanotec::cell_section::NanotecKeys;
        assert_eq!(
            names(&festo_cmmp_as::cell_section::KEYS),
            fields_of::<CmmpAsKeys>()
        );
        assert_eq!(
            names(&nanotec::cell_section::KEYS),
            fields_of::<NanotecKeys>()
        );
        assert_eq!(
            names(&kinco::cell_section::FD3_KEYS),
            fields_of::<KincoFd3Keys>()
        );
        assert_eq!(
            names(&kinco::cell_section::CD3_KEYS),
            fields_of::<KincoCd3Keys>()
        );
        assert_eq!(
            names(&festo_cmmo_st::cell_section::KEYS),
            fields_of::<CmmoStKeys>()
        );
        for section in CELL_SECTIONS {
            for device in section.devices {
                let desc = devices::by_name(device).expect(device);
                assert_eq!(
                    section_of(CELL_SECTIONS, device).map(|s| s.keys),
                    Some(section.keys),
                    "{device} is in one section"
                );
                for k in section.keys {
                    assert!(!COMMON_KEYS.contains(&k.name), "{}", k.name);
                    assert!(
                        !(crate::cell::device_model::is_cia402(desc)
                            && cia402::KEYS.iter().any(|c| c.name == k.name)),
                        "{device}: {}",
                        k.name
                    );
                }
            }
        }
        for desc in devices::ALL {
            assert!(
                desc.profile == od::Profile::Plain
                    || section_of(CELL_SECTIONS, desc.name).is_some(),
                "{} has no section of keys",
                desc.name
            );
        }
        // Every common key is read as one (none left for the sections).
        let all = "[[drive]]\ndevice = \"testbench\"\neds = \"x.eds\"\nnode = 2\nbus = \"b\"\n\
                   interfaces = []\nallow_unreal_interfaces = true\nethercat = \"veth0\"\n\
                   diagnostic = []\nplant = []\n[drive.objects]\n[drive.thermal]\n\
                   [drive.load]\nfmu = \"x.fmu\"\nload_torque = \"t\"\n";
        let f = file(all).unwrap();
        assert!(f.drive[0].rest.is_empty());
        assert_eq!(COMMON_KEYS.len(), 12);
    }
}
