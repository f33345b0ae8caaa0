//! The generic CiA 402 drive from an EDS / DCF as an EtherCAT slave: the CiA 402 drive profile
//! over CoE (ETG.6010), its dictionary the file's.
//!
//! An EDS describes a CANopen device: it has the PDO mapping objects 1600h–17FFh /
//! 1A00h–1BFFh but not the sync manager objects an EtherCAT slave adds (ETG.1000.6 §5.6.7.4:
//! 1C00h communication types, 1C12h / 1C13h PDO assignment). The drive on EtherCAT gets
//! them here, in a description of its own, so the CANopen drive of the same file keeps the
//! dictionary it has (no byte on CAN changes):
//!
//! * 1C00h: SM0 mailbox out (1), SM1 mailbox in (2), SM2 outputs (3), SM3 inputs (4).
//! * 1C12h: the RxPDOs 1600h… of the file, 1600h assigned by default; 1C13h the TxPDOs
//!   1A00h…, 1A00h assigned by default: the SII's defaults (`SiiConfig::BASELINE`), so the
//!   SII, the ESI and CoE say the same. A master assigns others in Pre-Op.
//! * The identity of the SII (words 8–0Dh) is `[DeviceInfo]`'s, which CiA 306 makes 1018h's;
//!   a file whose 1018h says otherwise is refused, as SOEM compares the two.
//!
//! Refused, each with what to change: a file that lists sync manager objects of its own
//! (1C00h–1C13h: the twin would not know which of the two layouts the SII should tell), a
//! file without 1600h or 1A00h (SM2 / SM3 have no default PDO), and more PDOs of one
//! direction than an assignment object can list.

use devdesc::model::{Device, Ent, Obj};
use od::{Access, DataType, Limit, ObjectKind};

/// What keeps an EDS drive off EtherCAT.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum EdsEthercatError {
    #[error(
        "{device}: the file lists {index:04X}h, a sync manager object of EtherCAT \
         (ETG.1000.6 §5.6.7.4); the twin adds 1C00h / 1C12h / 1C13h to a drive from an EDS \
         itself: remove it from the file"
    )]
    OwnSyncManagerObject { device: String, index: u16 },
    #[error(
        "{device}: no {index:04X}h, the PDO {sm} takes by default on EtherCAT (the SII's \
         default assignment): the file needs it"
    )]
    NoDefaultPdo {
        device: String,
        index: u16,
        sm: &'static str,
    },
    #[error(
        "{device}: {count} {what} PDOs; an assignment object (1C12h / 1C13h) lists at most 254"
    )]
    TooManyPdos {
        device: String,
        count: usize,
        what: &'static str,
    },
    #[error(
        "{device}: 1018h:{sub:02X} is {object:#010x} but [DeviceInfo] says {info:#010x}: the \
         SII's identity and CoE 1018h would differ (CiA 306: the two are one value)"
    )]
    Identity {
        device: String,
        sub: u8,
        object: u32,
        info: u32,
    },
}

/// The sync manager objects ETG.1000.6 §5.6.7.4 gives every CoE slave.
const SYNC_MANAGER_OBJECTS: std::ops::RangeInclusive<u16> = 0x1C00..=0x1C2F;

/// The device of `eds` as an EtherCAT slave: its objects with 1C00h, 1C12h and 1C13h added.
pub fn coe_device(eds: &Device) -> Result<Device, EdsEthercatError> {
    let device = || eds.name.clone();
    if let Some(o) = eds
        .objects
        .iter()
        .find(|o| SYNC_MANAGER_OBJECTS.contains(&o.index))
    {
        return Err(EdsEthercatError::OwnSyncManagerObject {
            device: device(),
            index: o.index,
        });
    }
    check_identity(eds)?;
    let pdos = |range: std::ops::RangeInclusive<u16>| -> Vec<u16> {
        eds.objects
            .iter()
            .map(|o| o.index)
            .filter(|i| range.contains(i))
            .collect()
    };
    let rx = pdos(0x1600..=0x17FF);
    let tx = pdos(0x1A00..=0x1BFF);
    for (list, first, sm, what) in [
        (&rx, 0x1600, "SM2 (outputs)", "receive"),
        (&tx, 0x1A00, "SM3 (inputs)", "transmit"),
    ] {
        if !list.contains(&first) {
            return Err(EdsEthercatError::NoDefaultPdo {
                device: device(),
                index: first,
                sm,
            });
        }
        if list.len() > 254 {
            return Err(EdsEthercatError::TooManyPdos {
                device: device(),
                count: list.len(),
                what,
            });
        }
    }
    let mut out = eds.clone();
    out.objects.push(communication_types());
    out.objects.push(assignment(0x1C12, "RxPDO assign", &rx));
    out.objects.push(assignment(0x1C13, "TxPDO assign", &tx));
    out.objects.sort_by_key(|o| o.index);
    Ok(out)
}

/// 1018h:01–03 as the file's defaults say, against `[DeviceInfo]` (the SII's identity).
fn check_identity(eds: &Device) -> Result<(), EdsEthercatError> {
    let Some(identity) = eds.objects.iter().find(|o| o.index == 0x1018) else {
        return Ok(());
    };
    for (sub, info) in [
        (1u8, eds.vendor_id),
        (2, eds.product_code),
        (3, eds.revision),
    ] {
        let object = identity
            .entries
            .iter()
            .find(|e| e.sub == sub)
            .and_then(|e| match od::Value::decode(e.data_type, &e.default) {
                Some(od::Value::Unsigned(v)) => u32::try_from(v).ok(),
                _ => None,
            });
        if let Some(object) = object.filter(|v| *v != info) {
            return Err(EdsEthercatError::Identity {
                device: eds.name.clone(),
                sub,
                object,
                info,
            });
        }
    }
    Ok(())
}

/// 1C00h sync manager communication types (ETG.1000.6 Table 67): mailbox out, mailbox in,
/// outputs, inputs.
fn communication_types() -> Obj {
    let mut entries = vec![Ent::plain(
        0x1C00,
        0,
        "Number of used sync manager channels".into(),
        DataType::Unsigned8,
        Access::ReadOnly,
        vec![4],
    )];
    for (sub, ty) in [(1u8, 1u8), (2, 2), (3, 3), (4, 4)] {
        entries.push(Ent::plain(
            0x1C00,
            sub,
            format!("Communication type SM{}", sub - 1),
            DataType::Unsigned8,
            Access::ReadOnly,
            vec![ty],
        ));
    }
    Obj {
        index: 0x1C00,
        name: "Sync manager communication type".into(),
        kind: ObjectKind::Array,
        min_max: None,
        entries,
    }
}

/// 1C12h / 1C13h: sub k may hold any PDO of `pdos`, sub 1 holds the first (assigned by
/// default, count 1) and sub k the k-th, as the CMMP-AS's device file lists them.
fn assignment(index: u16, name: &str, pdos: &[u16]) -> Obj {
    let n = u8::try_from(pdos.len()).unwrap_or(u8::MAX);
    let (low, high) = (
        pdos.first().copied().unwrap_or(0),
        pdos.last().copied().unwrap_or(0),
    );
    let mut count = Ent::plain(
        index,
        0,
        "Number of assigned PDOs".into(),
        DataType::Unsigned8,
        Access::ReadWrite,
        vec![1],
    );
    count.min = Some(Limit::Unsigned(0));
    count.max = Some(Limit::Unsigned(u64::from(n)));
    let mut entries = vec![count];
    for (k, pdo) in (1..=n).zip(pdos) {
        let mut e = Ent::plain(
            index,
            k,
            format!("PDO {k}"),
            DataType::Unsigned16,
            Access::ReadWrite,
            pdo.to_le_bytes().to_vec(),
        );
        e.min = Some(Limit::Unsigned(u64::from(low)));
        e.max = Some(Limit::Unsigned(u64::from(high)));
        entries.push(e);
    }
    Obj {
        index,
        name: name.into(),
        kind: ObjectKind::Array,
        min_max: None,
        entries,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cell::eds_drive;
    use crate::cell::eds_drive::test_files::data;

    fn u(desc: &od::DeviceDescription, index: u16, sub: u8) -> Option<u64> {
        let e = desc.entry(index, sub)?;
        match od::Value::decode(e.data_type, e.default)? {
            od::Value::Unsigned(v) => Some(v),
            _ => None,
        }
    }

    /// On EtherCAT the drive has the sync manager objects, 1600h / 1A00h assigned as the
    /// SII's defaults; on CANopen the file's dictionary stays as it is.
    #[test]
    fn the_drive_on_ethercat_has_the_sync_manager_objects() {
        let can = eds_drive::load(&data("epos4_like.eds")).unwrap();
        let ecat = eds_drive::on_ethercat(can).unwrap();
        assert!(!std::ptr::eq(can, ecat));
        assert!(std::ptr::eq(eds_drive::on_ethercat(can).unwrap(), ecat));
        assert!(std::ptr::eq(eds_drive::on_ethercat(ecat).unwrap(), ecat));
        assert_eq!(ecat.name, can.name);
        assert!(
            can.object(0x1C12).is_none(),
            "the CANopen dictionary is the file's"
        );
        let subs = |i| (0..=4).map(|s| u(ecat, i, s)).collect::<Vec<_>>();
        assert_eq!(subs(0x1C00), [4, 1, 2, 3, 4].map(Some));
        assert_eq!(
            subs(0x1C12),
            [
                Some(1),
                Some(0x1600),
                Some(0x1601),
                Some(0x1602),
                Some(0x1603)
            ]
        );
        assert_eq!(
            subs(0x1C13),
            [
                Some(1),
                Some(0x1A00),
                Some(0x1A01),
                Some(0x1A02),
                Some(0x1A03)
            ]
        );
        let sii = ethercat::sii::SiiConfig::from_description(ecat);
        assert_eq!(
            (sii.rx_assigned, sii.tx_assigned),
            (&[0x1600][..], &[0x1A00][..])
        );
        let p = eds_drive::personality_of(ecat).unwrap();
        assert!(p.modes.iter().any(|m| m.mode == 8), "CSP");
        assert_eq!(
            (u(ecat, 0x1018, 1), u(ecat, 0x1018, 2), u(ecat, 0x1018, 3)),
            (
                Some(u64::from(ecat.vendor_id)),
                Some(u64::from(ecat.product_code)),
                Some(u64::from(ecat.revision))
            )
        );
        assert!(std::ptr::eq(
            eds_drive::on_ethercat(&devices::CMMP_AS).unwrap(),
            &devices::CMMP_AS
        ));
    }

    /// What keeps a file off EtherCAT is named.
    #[test]
    fn unsupported_files_are_refused() {
        let eds = devdesc::eds::load_file(&data("epos4_like.eds"))
            .unwrap()
            .device;
        let mut own = eds.clone();
        let mut sm = communication_types();
        sm.index = 0x1C12;
        own.objects.push(sm);
        let e = coe_device(&own).unwrap_err();
        assert!(matches!(
            e,
            EdsEthercatError::OwnSyncManagerObject { index: 0x1C12, .. }
        ));
        assert!(e.to_string().contains("remove it"), "{e}");

        let mut no_rx = eds.clone();
        no_rx.objects.retain(|o| o.index != 0x1600);
        let e = coe_device(&no_rx).unwrap_err();
        assert!(
            matches!(e, EdsEthercatError::NoDefaultPdo { index: 0x1600, .. }),
            "{e}"
        );

        let mut other = eds.clone();
        other.vendor_id = 0x1234;
        let e = coe_device(&other).unwrap_err();
        assert!(
            matches!(
                e,
                EdsEthercatError::Identity {
                    sub: 1,
                    object: 0xFB,
                    info: 0x1234,
                    ..
                }
            ),
            "{e}"
        );
    }
}
