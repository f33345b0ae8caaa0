//! The object dictionary's access rules and CiA 301 behaviours, on the generated tables.

use od::eds::write_eds;
use od::parameter_file::{parse_line, write_line};
use od::{AbortCode, Access, DataType, ObjectAccess, ObjectDictionary, StorageRequest, Value};

fn testbench() -> ObjectDictionary<Vec<u8>> {
    let d = &devices::TESTBENCH;
    ObjectDictionary::new(d, 1, vec![0; d.storage_size]).unwrap()
}

#[test]
fn generated_tables_are_sorted_and_laid_out_without_overlap() {
    for d in devices::ALL {
        let mut last_index = None;
        let mut next_offset = 0usize;
        for o in d.objects {
            assert!(last_index < Some(o.index), "{}: objects sorted", d.name);
            last_index = Some(o.index);
            let mut last_sub = None;
            for e in o.entries {
                assert!(last_sub < Some(e.sub));
                last_sub = Some(e.sub);
                assert_eq!(e.offset as usize, next_offset, "{:04X}:{}", e.index, e.sub);
                next_offset += e.storage_len();
            }
        }
        assert_eq!(next_offset, d.storage_size);
    }
}

#[test]
fn too_small_storage_is_refused() {
    let d = &devices::TESTBENCH;
    assert!(ObjectDictionary::new(d, 1, vec![0u8; 10]).is_err());
}

#[test]
fn defaults_and_generated_sub_zero() {
    let od = testbench();
    assert_eq!(od.value(0x2004, 2), Some(Value::Signed(-8)));
    assert_eq!(od.value(0x2004, 10), Some(Value::Real(1.5)));
    assert_eq!(
        od.value(0x2004, 0),
        Some(Value::Unsigned(12)),
        "highest sub-index"
    );
    let e = devices::TESTBENCH.entry(0x2004, 0).unwrap();
    assert_eq!(e.access, Access::ReadOnly);
    assert_eq!(e.data_type, DataType::Unsigned8);
    let mut buf = [0u8; 16];
    assert_eq!(od.read(0x2004, 12, &mut buf), Ok(4));
    assert_eq!(&buf[..4], &[0xDE, 0xAD, 0xBE, 0xEF]);
}

#[test]
fn strings_end_at_their_first_nul_and_respect_their_size() {
    let mut od = testbench();
    od.write(0x2001, 0, b"abc\0def").unwrap();
    let mut buf = vec![0u8; 5000];
    assert_eq!(od.read(0x2001, 0, &mut buf), Ok(3));
    assert_eq!(
        od.write(0x2001, 0, &vec![b'x'; 4097]),
        Err(AbortCode::LENGTH_TOO_HIGH)
    );
    assert_eq!(
        od.read(0x2001, 0, &mut buf[..2]),
        Err(AbortCode::OUT_OF_MEMORY)
    );
}

#[test]
fn boolean_accepts_only_zero_and_one() {
    let mut od = testbench();
    assert_eq!(od.write(0x2004, 1, &[2]), Err(AbortCode::INVALID_VALUE));
    od.write(0x2004, 1, &[1]).unwrap();
    assert_eq!(od.value(0x2004, 1), Some(Value::Bool(true)));
}

#[test]
fn store_and_restore_signatures() {
    let mut od = testbench();
    od.write(0x1017, 0, &[0x64, 0]).unwrap();
    assert_eq!(od.write(0x1010, 1, b"save"), Ok(()));
    assert_eq!(od.take_request(), Some(StorageRequest::Save { sub: 1 }));
    assert_eq!(od.take_request(), None);
    assert_eq!(od.write(0x1010, 1, b"load"), Err(AbortCode::CANNOT_STORE));
    assert_eq!(od.write(0x1010, 1, b"sav"), Err(AbortCode::LENGTH_TOO_LOW));
    assert_eq!(od.write(0x1011, 1, b"load"), Ok(()));
    assert_eq!(
        od.get_unsigned(0x1017, 0),
        Some(0),
        "defaults restored at once"
    );
    assert_eq!(
        od.get_unsigned(0x1010, 1),
        Some(1),
        "signatures keep reading 1"
    );
}

#[test]
fn storable_values_cover_the_writable_parameters_only() {
    let od = testbench();
    let keys: Vec<(u16, u8)> = od
        .storable_values(1)
        .map(|(e, _)| (e.index, e.sub))
        .collect();
    assert!(keys.contains(&(0x1017, 0)));
    assert!(keys.contains(&(0x2001, 0)));
    assert!(
        !keys.contains(&(0x1010, 1)),
        "the signature entries are commands"
    );
    assert!(!keys.contains(&(0x1018, 1)), "read-only");
    let comm: Vec<(u16, u8)> = od
        .storable_values(2)
        .map(|(e, _)| (e.index, e.sub))
        .collect();
    assert!(comm.iter().all(|(i, _)| (0x1000..0x2000).contains(i)));
}

#[test]
fn parameter_file_lines_round_trip() {
    let od = testbench();
    let mut text = String::new();
    for (e, bytes) in od.storable_values(1) {
        write_line(&mut text, e, bytes).unwrap();
    }
    let mut od2 = testbench();
    od2.write(0x2003, 0, &[5, 0]).unwrap();
    let mut buf = vec![0u8; 9000];
    for line in text.lines() {
        let (index, sub, n) = parse_line(line, &mut buf).unwrap().unwrap();
        let e = devices::TESTBENCH.entry(index, sub).unwrap();
        od2.store(e, &buf[..n]);
    }
    assert_eq!(od2.value(0x2003, 0), Some(Value::Signed(0)));
}

#[test]
fn eds_lists_every_object_with_node_relative_defaults() {
    let mut text = String::new();
    write_eds(&mut text, &devices::CMMP_AS, "01-01-2026").unwrap();
    for o in devices::CMMP_AS.objects {
        assert!(
            text.contains(&format!("[{:04X}]", o.index)),
            "{:04X}",
            o.index
        );
    }
    assert!(
        text.contains("[1800sub1]\nParameterName=cob_id_used_by_pdo_tpdo1"),
        "{}",
        &text[..200]
    );
    assert!(text.contains("DefaultValue=$NODEID+0xC0000180"));
    assert!(text.contains("VendorNumber=0x1D"));
}
