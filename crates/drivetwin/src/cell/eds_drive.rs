//! A CiA 402 drive from its EDS or DCF (CiA 306): the dictionary is the file's, the modes
//! are those its 6502h supported_drive_modes and its objects allow, the homing methods those
//! of 60E3h (or every method the engine knows), the motor the default servo motor.
//!
//! The description and the personality are built once per file at start-up and leaked: the
//! `no_std` engine holds `&'static` tables ([`devdesc::runtime`]), and a loaded drive lives as
//! long as the process. A file named twice (a cell file and `--eds`) is read once.
//!
//! A DCF's commissioned bit rate (`[DeviceComissioning] Baudrate`) is the rate the node is set
//! to, as a built-in device's switches or objects set its rate ([`bit_rate_of`],
//! [`crate::cell::bus_rate`]); an EDS sets none, and its node follows the bus.
//!
//! The drive runs on CANopen or, its dictionary served over CoE, on EtherCAT (one at a time,
//! as a drive with both interfaces usually offers them): on EtherCAT it has a description of
//! its own, the file's objects and the sync manager objects ([`on_ethercat`],
//! [`crate::cell::eds_ethercat`]).

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use devdesc::eds::{BitRate, EdsError};
use devdesc::model::Device;
use drive::drive::mode;
use drive::homing::{Method, METHODS};
use drive::personality::{ModeSpec, Personality};
use drive::vendors::cia402::{CIA402, CIA402_FEED_CONSTANT};
use od::DeviceDescription;

use crate::cell::eds_ethercat::{self, EdsEthercatError};

/// A file read, its description and the personality the engine runs it with.
struct Loaded {
    path: PathBuf,
    desc: &'static DeviceDescription,
    personality: &'static Personality,
    /// A DCF's `[DeviceComissioning] Baudrate`.
    bit_rate: Option<BitRate>,
    /// The device as read, for its description on EtherCAT.
    device: Device,
    /// The drive on EtherCAT: its description with the sync manager objects, and its
    /// personality; made the first time a drive of the file goes on a chain.
    ethercat: Option<(&'static DeviceDescription, &'static Personality)>,
}

/// Every EDS / DCF loaded by this process.
static LOADED: Mutex<Vec<Loaded>> = Mutex::new(Vec::new());

/// The description of the CiA 402 drive the EDS / DCF at `path` describes, read and checked
/// on the first call for the file.
pub fn load(path: &Path) -> Result<&'static DeviceDescription, EdsError> {
    let key = path.canonicalize().unwrap_or_else(|_| path.to_path_buf());
    let mut loaded = LOADED.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(l) = loaded.iter().find(|l| l.path == key) {
        return Ok(l.desc);
    }
    let eds = devdesc::eds::load_file(path)?;
    eds.require_cia402()?;
    let bit_rate = eds.bit_rate;
    let mut device = eds.device;
    // The name tells drives apart in the console and the API: never a built-in device's,
    // never another file's.
    let base = if devices::by_name(&device.name).is_some() {
        format!("eds-{}", device.name)
    } else {
        device.name.clone()
    };
    device.name = base.clone();
    device.interfaces = vec!["canopen".into(), "ethercat".into()];
    device.interfaces_one_of = device.interfaces.clone();
    device.interfaces_rule =
        "a CiA 402 drive from its EDS: CANopen, or its dictionary over EtherCAT (CoE, ETG.6010)"
            .into();
    let mut n = 2;
    while loaded.iter().any(|l| l.desc.name == device.name) {
        device.name = format!("{base}-{n}");
        n += 1;
    }
    let desc = devdesc::runtime::leak(&device);
    let personality = Box::leak(Box::new(personality(desc)));
    loaded.push(Loaded {
        path: key,
        desc,
        personality,
        bit_rate,
        device,
        ethercat: None,
    });
    Ok(desc)
}

/// The description a drive of `desc` has as an EtherCAT slave: for a drive from an EDS its
/// own, with the sync manager objects ([`eds_ethercat::coe_device`]), made once per file;
/// a built-in device's is its own.
pub fn on_ethercat(
    desc: &'static DeviceDescription,
) -> Result<&'static DeviceDescription, EdsEthercatError> {
    let mut loaded = LOADED.lock().unwrap_or_else(|e| e.into_inner());
    let Some(l) = loaded.iter_mut().find(|l| {
        std::ptr::eq(l.desc, desc) || l.ethercat.is_some_and(|(d, _)| std::ptr::eq(d, desc))
    }) else {
        return Ok(desc);
    };
    if let Some((d, _)) = l.ethercat {
        return Ok(d);
    }
    let on_ethercat = devdesc::runtime::leak(&eds_ethercat::coe_device(&l.device)?);
    let personality: &'static Personality = Box::leak(Box::new(personality(on_ethercat)));
    l.ethercat = Some((on_ethercat, personality));
    Ok(on_ethercat)
}

/// The personality of a drive loaded from an EDS (on CANopen or on EtherCAT); `None` for a
/// built-in device.
pub fn personality_of(desc: &DeviceDescription) -> Option<&'static Personality> {
    let loaded = LOADED.lock().unwrap_or_else(|e| e.into_inner());
    loaded.iter().find_map(|l| {
        if std::ptr::eq(l.desc, desc) {
            return Some(l.personality);
        }
        l.ethercat
            .filter(|(d, _)| std::ptr::eq(*d, desc))
            .map(|(_, p)| p)
    })
}

/// The bit rate the DCF of a drive loaded from one is commissioned to; `None` for an EDS
/// without `[DeviceComissioning] Baudrate` and for a built-in device.
pub fn bit_rate_of(desc: &DeviceDescription) -> Option<BitRate> {
    let loaded = LOADED.lock().unwrap_or_else(|e| e.into_inner());
    loaded
        .iter()
        .find(|l| std::ptr::eq(l.desc, desc))
        .and_then(|l| l.bit_rate.clone())
}

/// A built-in device, or a drive loaded from an EDS, by its name.
pub fn by_name(name: &str) -> Option<&'static DeviceDescription> {
    devices::by_name(name).or_else(|| {
        let loaded = LOADED.lock().unwrap_or_else(|e| e.into_inner());
        loaded.iter().find(|l| l.desc.name == name).map(|l| l.desc)
    })
}

/// The dictionary a station of the drive named `name` serves: an EtherCAT slave alone
/// (`ethercat_only`) serves the description its slave was built with, the sync manager
/// objects 1C00h / 1C12h / 1C13h included ([`on_ethercat`]); a CANopen node serves the file's.
pub fn served(name: &str, ethercat_only: bool) -> Option<&'static DeviceDescription> {
    let desc = by_name(name)?;
    if !ethercat_only {
        return Some(desc);
    }
    Some(on_ethercat(desc).unwrap_or(desc))
}

/// The objects a mode cannot run without (its 6060h value, the objects).
const MODE_OBJECTS: [(i8, &[u16]); 7] = [
    (mode::PROFILE_POSITION, &[0x607A, 0x6081]),
    (mode::VELOCITY, &[0x6042]),
    (mode::PROFILE_VELOCITY, &[0x60FF]),
    (mode::PROFILE_TORQUE, &[0x6071]),
    (mode::HOMING, &[0x6098]),
    (mode::INTERPOLATED_POSITION, &[0x60C1]),
    (mode::CYCLIC_SYNCHRONOUS_POSITION, &[0x607A]),
];

/// The generic CiA 402 personality of `desc`: CiA 402's defaults where the engine asks a
/// personality, the modes and homing methods from the file.
///
/// The behaviour a table cannot hold is the standard CiA 402 vendor's
/// ([`drive::vendors::Cia402`]): every hook at CiA 402's default.
fn personality(desc: &'static DeviceDescription) -> Personality {
    let has = |index: u16| desc.object(index).is_some();
    // Without 6502h the objects alone say which modes there are.
    let supported = desc
        .entry(0x6502, 0)
        .and_then(|e| od::Value::decode(e.data_type, e.default))
        .and_then(|v| match v {
            od::Value::Unsigned(u) => Some(u),
            _ => None,
        });
    // The standard drive's modes (their 6502h bits), narrowed to the file's 6502h and to
    // those whose objects the file has.
    let runnable = |m: &ModeSpec| {
        MODE_OBJECTS
            .iter()
            .find(|(mode, _)| *mode == m.mode)
            .is_some_and(|(_, needs)| needs.iter().all(|i| has(*i)))
    };
    let modes: Vec<ModeSpec> = CIA402
        .modes
        .iter()
        .filter(|m| {
            m.bit
                .is_some_and(|bit| supported.is_none_or(|s| s & (1 << bit) != 0))
                && runnable(m)
        })
        .copied()
        .collect();
    // 60E3h supported_homing_methods (CiA 402 §8.4.1): sub 1… each a method.
    let listed: Option<Vec<i64>> = desc.object(0x60E3).map(|o| {
        o.entries
            .iter()
            .filter(|e| e.sub > 0)
            .filter_map(|e| match od::Value::decode(e.data_type, e.default) {
                Some(od::Value::Signed(s)) => Some(s),
                Some(od::Value::Unsigned(u)) => i64::try_from(u).ok(),
                _ => None,
            })
            .collect()
    });
    let homing_methods: Vec<Method> = METHODS
        .iter()
        .copied()
        .filter(|(m, _)| listed.as_ref().is_none_or(|l| l.contains(&i64::from(*m))))
        .collect();
    // The standard CiA 402 drive's personality, narrowed to what the file offers.
    let base = if has(0x6092) {
        &CIA402_FEED_CONSTANT
    } else {
        &CIA402
    };
    Personality {
        devices: Box::leak(vec![desc.name].into_boxed_slice()),
        modes: Box::leak(modes.into_boxed_slice()),
        homing_methods: Box::leak(homing_methods.into_boxed_slice()),
        ..*base
    }
}

/// The test EDS files of `tests/interop/data/eds/` (written after other vendors' public
/// object lists), for the tests of the modules that read them.
#[cfg(test)]
pub(crate) mod test_files {
    use std::path::{Path, PathBuf};

    /// The test EDS or DCF file `name`.
    pub(crate) fn data(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../tests/interop/data/eds")
            .join(name)
    }
}

#[cfg(test)]
mod tests {
    use super::test_files::data;
    use super::*;
    use drive::drive::{Drive, DriveSettings};
    use drive::vendors::Cia402;
    use od::{Instant, ObjectAccess, ObjectDictionary};

    fn modes(p: &Personality) -> Vec<i8> {
        p.modes.iter().map(|m| m.mode).collect()
    }

    #[test]
    fn modes_and_homing_methods_from_the_file() {
        let epos = load(&data("epos4_like.eds")).unwrap();
        let p = personality_of(epos).unwrap();
        // 6502h = PPM, PVM, HMM, CSP, CSV, CST: CSV and CST the engine does not run.
        assert_eq!(modes(p), [1, 3, 6, 8]);
        assert_eq!(
            p.homing_methods.len(),
            METHODS.len(),
            "no 60E3h: every method"
        );
        let lxm = load(&data("lexium32_like.eds")).unwrap();
        let p = personality_of(lxm).unwrap();
        // 6502h = PP, PV, PT, HM, IP, CSP, CSV, CST; IP has its 60C1h.
        assert_eq!(modes(p), [1, 3, 4, 6, 7, 8]);
        let methods: Vec<i8> = p.homing_methods.iter().map(|(m, _)| *m).collect();
        assert_eq!(methods, [1, 2, 7, 11, 17, 18, 23, 27, 33, 34, 35]);
        // Read once: the same description again, found by its name too.
        assert!(std::ptr::eq(load(&data("epos4_like.eds")).unwrap(), epos));
        assert!(std::ptr::eq(by_name("lexium32-like").unwrap(), lxm));
        assert!(personality_of(&devices::CMMP_AS).is_none());
    }

    /// The generic drive on the engine: enabled by its controlword alone, a PP move, homing
    /// method 35 on the spot (CiA 402 §8.4, the actual position is the home position).
    #[test]
    fn enable_move_and_home_on_the_virtual_clock() {
        let desc = load(&data("lexium32_like.eds")).unwrap();
        let od = ObjectDictionary::new(desc, 5, vec![0; desc.storage_size]).unwrap();
        assert_eq!(
            od.get_unsigned(0x1800, 1),
            Some(0x4000_0185),
            "$NODEID+0x40000180"
        );
        let mut d = Drive::with_vendor(
            od,
            DriveSettings::default(),
            personality_of(desc).unwrap(),
            Cia402,
        );
        let mut now = Instant::ZERO;
        let mut run = |d: &mut Drive<Vec<u8>, Cia402>, ms: u64| {
            for _ in 0..ms {
                now = now + core::time::Duration::from_millis(1);
                d.step(now);
            }
        };
        let sw = |d: &Drive<Vec<u8>, Cia402>| d.od().get_unsigned(0x6041, 0).unwrap();
        run(&mut d, 10);
        d.write(0x6060, 0, &[1]).unwrap();
        for cw in [0x06u16, 0x0F] {
            d.write(0x6040, 0, &cw.to_le_bytes()).unwrap();
            run(&mut d, 20);
        }
        assert_eq!(sw(&d) & 0x6F, 0x27, "OPERATION ENABLED: {:#06x}", sw(&d));
        d.write(0x607A, 0, &20_000i32.to_le_bytes()).unwrap();
        d.write(0x6040, 0, &0x1Fu16.to_le_bytes()).unwrap();
        run(&mut d, 3000);
        let pos = d.od().value(0x6064, 0);
        assert!(
            sw(&d) & 0x0400 != 0,
            "target reached: {:#06x}, 6064h {pos:?}",
            sw(&d)
        );
        // Within the position window 6067h = 16 of the file.
        assert!(
            matches!(pos, Some(od::Value::Signed(p)) if (p - 20_000).abs() <= 16),
            "{pos:?}"
        );
        // 6098h refuses a method the file lists but the engine does not run.
        assert!(d.write(0x6098, 0, &[3]).is_err());
        d.write(0x6098, 0, &[35]).unwrap();
        d.write(0x607C, 0, &1000i32.to_le_bytes()).unwrap();
        d.write(0x6060, 0, &[6]).unwrap();
        d.write(0x6040, 0, &0x0Fu16.to_le_bytes()).unwrap();
        run(&mut d, 20);
        d.write(0x6040, 0, &0x1Fu16.to_le_bytes()).unwrap();
        run(&mut d, 100);
        assert_eq!(sw(&d) & 0x3400, 0x1400, "homing attained: {:#06x}", sw(&d));
        assert_eq!(d.od().value(0x6064, 0), Some(od::Value::Signed(1000)));
    }
}

#[cfg(test)]
mod cell_file_tests {
    use crate::cell::config::{CellFile, ConfigError};

    /// `eds = "…"` is relative to the cell file; `device` and `eds` together are refused; a
    /// broken file is refused with its line.
    #[test]
    fn eds_on_a_drive_of_a_cell_file() {
        let dir = std::env::temp_dir().join(format!("drivetwin-eds-cell-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("drives")).unwrap();
        let source = super::test_files::data("epos4_like.eds");
        let text = std::fs::read_to_string(&source).unwrap();
        std::fs::write(dir.join("drives/axis.eds"), &text).unwrap();
        let cell = dir.join("cell.toml");
        std::fs::write(&cell, "[[drive]]\neds = \"drives/axis.eds\"\nnode = 4\n").unwrap();
        let specs = CellFile::load(&cell)
            .unwrap()
            .drives(crate::cell::Vendors::NONE)
            .unwrap();
        assert_eq!(specs[0].desc.name, "axis");
        assert_eq!(specs[0].node, 4);
        assert!(
            specs[0].settings.is_some(),
            "a CiA 402 drive with its motor"
        );

        std::fs::write(
            &cell,
            "[[drive]]\ndevice = \"nanotec-pd4n\"\neds = \"drives/axis.eds\"\n",
        )
        .unwrap();
        let err = CellFile::load(&cell)
            .unwrap()
            .drives(crate::cell::Vendors::NONE)
            .unwrap_err();
        assert!(err.to_string().contains("not both"), "{err}");

        let broken = text.replacen("AccessType=rw\n", "AccessType=rx\n", 1);
        let line = broken.lines().position(|l| l == "AccessType=rx").unwrap() + 1;
        std::fs::write(dir.join("drives/broken.eds"), broken).unwrap();
        std::fs::write(&cell, "[[drive]]\neds = \"drives/broken.eds\"\n").unwrap();
        let err = CellFile::load(&cell)
            .unwrap()
            .drives(crate::cell::Vendors::NONE)
            .unwrap_err();
        assert!(matches!(err, ConfigError::Eds(_)));
        let path = dir.join("drives/broken.eds");
        assert!(
            err.to_string()
                .starts_with(&format!("{}:{line}: [", path.display())),
            "{err}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}

#[cfg(test)]
mod dcf_bit_rate_tests {
    use crate::cell::bus_rate::BusRate;
    use crate::cell::config::{CellFile, ConfigError};
    use std::path::{Path, PathBuf};

    /// A DCF after the EPOS4-like EDS, commissioned to `kbit`, written as `dir/name`.
    fn dcf(dir: &Path, name: &str, kbit: u16) -> PathBuf {
        let source = super::test_files::data("epos4_like.eds");
        let text = std::fs::read_to_string(source).unwrap();
        let path = dir.join(name);
        std::fs::write(
            &path,
            format!("{text}\n[DeviceComissioning]\nNodeID=4\nBaudrate={kbit}\n"),
        )
        .unwrap();
        path
    }

    fn rates(cell: &Path) -> Result<Vec<BusRate>, ConfigError> {
        let file = CellFile::load(cell)?;
        file.bus_rates(&file.drives(crate::cell::Vendors::NONE)?)
    }

    /// A DCF's `Baudrate` is its node's rate: the bus takes it (`eds = "…"` and `--eds`);
    /// two DCFs at different rates are refused naming both files; a named `bitrate` wins
    /// (the DCF's node at another rate stays silent, as any node set to another rate). Its
    /// `NodeID` is the drive's node-ID where the cell file names none.
    #[test]
    fn a_dcf_sets_the_bus_rate() {
        let dir = std::env::temp_dir().join(format!("drivetwin-dcf-rate-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let a = dcf(&dir, "axis_a.dcf", 500);
        let b = dcf(&dir, "axis_b.dcf", 250);
        let cell = dir.join("cell.toml");
        let timed = |bitrate, from_nodes| BusRate::Timed {
            bitrate,
            from_nodes,
        };

        std::fs::write(&cell, "[[drive]]\neds = \"axis_a.dcf\"\nnode = 4\n").unwrap();
        assert_eq!(rates(&cell).unwrap(), [timed(500_000, true)]);
        let single = CellFile::single_eds(&a, Some(4)).unwrap();
        assert_eq!(
            single
                .bus_rates(&single.drives(crate::cell::Vendors::NONE).unwrap())
                .unwrap(),
            [timed(500_000, true)]
        );

        let two = "[[drive]]\neds = \"axis_a.dcf\"\nnode = 4\n\
                   [[drive]]\neds = \"axis_b.dcf\"\nnode = 5\n";
        std::fs::write(&cell, two).unwrap();
        let err = rates(&cell).unwrap_err();
        let text = err.to_string();
        assert!(matches!(err, ConfigError::BusRate(_)), "{text}");
        for (file, kbit) in [(&a, 500), (&b, 250)] {
            assert!(
                text.contains(&format!("{kbit} kbit/s, set by {}:", file.display()))
                    && text.contains("[DeviceComissioning] Baudrate"),
                "{text}"
            );
        }

        std::fs::write(&cell, format!("[bus]\nbitrate = 1000000\n{two}")).unwrap();
        assert_eq!(rates(&cell).unwrap(), [timed(1_000_000, false)]);
        let mut single = CellFile::single_eds(&b, Some(4)).unwrap();
        single.set_bitrate(crate::cell::bus_rate::BitrateSetting::Bits(500_000));
        let specs = single.drives(crate::cell::Vendors::NONE).unwrap();
        assert_eq!(single.bus_rates(&specs).unwrap(), [timed(500_000, false)]);
        assert_eq!(specs[0].bit_rate.as_ref().map(|r| r.kbit), Some(250));

        // Without `node` a drive from a DCF is at its `[DeviceComissioning] NodeID`.
        std::fs::write(&cell, "[[drive]]\neds = \"axis_a.dcf\"\n").unwrap();
        let specs = CellFile::load(&cell)
            .unwrap()
            .drives(crate::cell::Vendors::NONE)
            .unwrap();
        assert_eq!(specs[0].node, 4);
        // `drivetwin run --eds` without --node: the same.
        let specs = CellFile::single_eds(&a, None)
            .unwrap()
            .drives(crate::cell::Vendors::NONE)
            .unwrap();
        assert_eq!(specs[0].node, 4);
        std::fs::write(&cell, "[[drive]]\neds = \"axis_a.dcf\"\nnode = 9\n").unwrap();
        let specs = CellFile::load(&cell)
            .unwrap()
            .drives(crate::cell::Vendors::NONE)
            .unwrap();
        assert_eq!(specs[0].node, 9);

        // A DCF beside a built-in drive at its rate: they agree.
        std::fs::write(
            &cell,
            "[[drive]]\neds = \"axis_b.dcf\"\nnode = 4\n\
             [[drive]]\ndevice = \"kinco-fd3\"\nnode = 2\n[drive.objects]\n\"2F81:00\" = 25\n",
        )
        .unwrap();
        assert_eq!(rates(&cell).unwrap(), [timed(250_000, true)]);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
