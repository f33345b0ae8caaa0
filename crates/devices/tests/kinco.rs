//! The two Kinco personalities (the Kinco CD3 / FD3 manual, kept beside the project with its
//! English extract): what the FD3 (CANopen) and the CD3 have, the defaults and ranges the manual
//! prints, and the panel address and Modbus register of each object. The manual's worked examples
//! by their vector IDs (the catalogue of the manuals' worked examples kept beside the project).

use od::{AbortCode, DataType, ObjectAccess, ObjectDictionary, Profile, Value};

fn od(d: &'static od::DeviceDescription, node: u8) -> ObjectDictionary<Vec<u8>> {
    ObjectDictionary::new(d, node, vec![0; d.storage_size]).unwrap()
}

fn fd3() -> ObjectDictionary<Vec<u8>> {
    od(&devices::KINCO_FD3, 1)
}

fn addr(name: &str) -> &'static devices::Addresses {
    devices::addresses(name).unwrap()
}

/// §1.1 / Tab. 3-7: the CD3 has no fieldbus port; the FD3-CA adds CANopen and the DIP
/// switches. Both share the firmware's parameter list (ch. 9).
#[test]
fn fd3_has_canopen_and_dip_station_cd3_has_neither() {
    let fd3 = &devices::KINCO_FD3;
    let cd3 = &devices::KINCO_CD3;
    for d in [fd3, cd3] {
        assert_eq!(d.profile, Profile::Cia402);
        for i in [
            0x1000, 0x100B, 0x1018, 0x2000, 0x2010, 0x2020, 0x2340, 0x2508, 0x2509, 0x2601, 0x2605,
            0x2FE0, 0x2FE2, 0x2FF0, 0x3040, 0x6040, 0x6041, 0x6060, 0x607A, 0x60F9, 0x60FF, 0x6410,
            0x6510,
        ] {
            assert!(d.object(i).is_some(), "{}: {i:04X}h", d.name);
        }
        assert!(
            d.object(0x1010).is_none(),
            "saved through 2FF0h:01, no 1010h"
        );
    }
    for i in [
        0x1005, 0x1014, 0x1017, 0x1200, 0x1400, 0x1600, 0x1803, 0x1A03, 0x2F80, 0x2F81,
    ] {
        assert!(fd3.object(i).is_some(), "FD3 {i:04X}h");
        assert!(cd3.object(i).is_none(), "CD3 {i:04X}h");
    }
    assert!(addr("kinco-cd3").modbus.is_empty(), "the CD3 has no RS485");
    assert_eq!(
        od(cd3, 1).get_unsigned(0x1018, 2),
        Some(0xCD3),
        "tells itself apart"
    );
}

/// KINCO-DIP-06: with SW1…SW8 all OFF the station number comes from EEPROM, changeable in
/// 2F80h:01, printed "0x2F800108" (8 bit).
#[test]
fn kinco_dip_06_station_object() {
    let e = devices::KINCO_FD3.entry(0x2F80, 1).unwrap();
    assert_eq!(e.data_type, DataType::Unsigned8);
    assert!(e.storable, "needs save and reboot");
    let e = devices::KINCO_FD3.entry(0x100B, 0).unwrap();
    assert_eq!((e.data_type, e.default), (DataType::Unsigned8, &[1u8][..]));
}

/// KINCO-232-10: RS232_Baudrate 2FE0h (default 270 = 38400), U2BRG 2FE1h (at once, not
/// saved), RS485_Baudrate 2FE2h (default 540 = 19200); code = 10 368 000 / bit rate.
#[test]
fn kinco_232_10_baud_rate_codes() {
    let od = fd3();
    assert_eq!(od.get_unsigned(0x2FE0, 0), Some(270));
    assert_eq!(od.get_unsigned(0x2FE1, 0), Some(270));
    assert_eq!(od.get_unsigned(0x2FE2, 0), Some(540));
    for (code, baud) in [(540u32, 19200u32), (270, 38400), (90, 115200), (1080, 9600)] {
        assert_eq!(10_368_000 / baud, code);
    }
    assert_eq!(
        10_368_000 / od.get_unsigned(0x2FE0, 0).unwrap() as u32,
        38400
    );
    assert_eq!(
        10_368_000 / od.get_unsigned(0x2FE2, 0).unwrap() as u32,
        19200
    );
    assert!(devices::KINCO_FD3.entry(0x2FE0, 0).unwrap().storable);
    assert!(!devices::KINCO_FD3.entry(0x2FE1, 0).unwrap().storable);
    let a = addr("kinco-fd3");
    assert_eq!(a.panel("d5.02"), Some((0x2FE0, 0)));
    assert_eq!(a.panel("d5.03"), Some((0x2FE1, 0)));
    assert_eq!(a.panel("d5.18"), Some((0x2FE2, 0)));
}

/// KINCO-232-10: the FD3's and the CD3's `serial_bit_rate` list 2FE0h-2FE2h with the four
/// codes of §9.5, each 10 368 000 / its bit rate; 135 (76 800 bit/s) is not listed.
#[test]
fn kinco_232_10_serial_bit_rate_table() {
    for desc in [&devices::KINCO_FD3, &devices::KINCO_CD3] {
        let s = desc.serial_bit_rate.expect("serial_bit_rate");
        assert_eq!(s.objects, [0x2FE0, 0x2FE1, 0x2FE2]);
        assert_eq!(
            s.codes,
            [(1080, 9600), (540, 19200), (270, 38400), (90, 115_200)]
        );
        for &(code, baud) in s.codes {
            assert_eq!(u32::from(code), 10_368_000 / baud);
            assert_eq!(s.code(baud), Some(code));
            assert_eq!(s.bit_rate(code), Some(baud));
        }
        assert_eq!(s.bit_rate(135), None, "76800 is not listed");
    }
}

/// KINCO-CAN-05: the predefined connection set of node 1 (EMCY 081h, TPDO 181h…481h,
/// RPDO 201h…501h, SDO 581h / 601h); the EMCY COB-ID is 1014h (printed "1024H").
#[test]
fn kinco_can_05_cob_ids_of_node_1() {
    let od = fd3();
    let cob = |i: u16, s: u8| od.get_unsigned(i, s).map(|v| v & 0x7FF);
    assert_eq!(cob(0x1014, 0), Some(0x081));
    for n in 0..4u16 {
        assert_eq!(cob(0x1800 + n, 1), Some(0x181 + 0x100 * n as u64));
        assert_eq!(cob(0x1400 + n, 1), Some(0x201 + 0x100 * n as u64));
    }
    assert_eq!(cob(0x1200, 1), Some(0x601));
    assert_eq!(cob(0x1200, 2), Some(0x581));
    assert_eq!(od.get_unsigned(0x1005, 0), Some(0x80));
    // Node 5: the COB-IDs follow the node-ID.
    assert_eq!(od_node(5).get_unsigned(0x1014, 0), Some(0x85));
}

fn od_node(node: u8) -> ObjectDictionary<Vec<u8>> {
    od(&devices::KINCO_FD3, node)
}

/// KINCO-CAN-06: CAN_Baudrate 2F81h (8 bit, d5.17) defaults to 50 = 500 kbit/s; the codes
/// 100, 50, 25, 12, 5 are 1 M, 500 k, 250 k, 125 k and 50 k, the device's bit rates.
#[test]
fn kinco_can_06_can_baudrate() {
    let od = fd3();
    assert_eq!(od.get_unsigned(0x2F81, 0), Some(50));
    assert_eq!(
        devices::KINCO_FD3.entry(0x2F81, 0).unwrap().data_type,
        DataType::Unsigned8
    );
    assert_eq!(addr("kinco-fd3").panel("d5.17"), Some((0x2F81, 0)));
    assert_eq!(devices::KINCO_FD3.baud_rates, &[50, 125, 250, 500, 1000]);
}

/// KINCO-CAN-07: the TPDO inhibit time is UNSIGNED16 in 100 µs (10 = 1 ms).
#[test]
fn kinco_can_07_inhibit_time_unit() {
    for n in 0..4 {
        let e = devices::KINCO_FD3.entry(0x1800 + n, 3).unwrap();
        assert_eq!(e.data_type, DataType::Unsigned16);
        assert_eq!(e.unit, "100 us");
    }
    // CiA 301: only while the PDO is not valid (TPDO2 ships with bit 31 set).
    let mut od = fd3();
    od.write(0x1801, 3, &10u16.to_le_bytes()).unwrap();
    assert_eq!(od.get_unsigned(0x1801, 3), Some(10));
}

/// KINCO-CW-06 (the object part): Din_Controlword 2020h:0F (d3.38) defaults to 2Fh, the
/// controlword the Enable DIN writes; the factory DIN/DOUT functions of ch. 9.
#[test]
fn kinco_cw_06_din_controlword_and_factory_functions() {
    let od = fd3();
    assert_eq!(od.get_unsigned(0x2020, 0x0F), Some(0x2F));
    let a = addr("kinco-fd3");
    assert_eq!(a.panel("d3.38"), Some((0x2020, 0x0F)));
    for (k, f) in [0x01u64, 0x02, 0x04, 0x08, 0x10, 0x20, 0x40]
        .iter()
        .enumerate()
    {
        assert_eq!(
            od.get_unsigned(0x2010, 3 + k as u8),
            Some(*f),
            "DIN{}",
            k + 1
        );
        let key = format!("d3.{:02}", k + 1);
        assert_eq!(a.panel(&key), Some((0x2010, 3 + k as u8)));
    }
    for (k, f) in [0x01u64, 0x10, 0x04, 0x08, 0x02].iter().enumerate() {
        assert_eq!(
            od.get_unsigned(0x2010, 0x0F + k as u8),
            Some(*f),
            "OUT{}",
            k + 1
        );
    }
    assert_eq!(od.value(0x2020, 0x0D), Some(Value::Signed(-4)), "Din_Mode0");
    assert_eq!(od.value(0x2020, 0x0E), Some(Value::Signed(-3)), "Din_Mode1");
}

/// KINCO-SC-06: Notch_N 60F9h:03 (d2.03) defaults to 45 (550 Hz); 500 Hz is Notch_N 40;
/// range 0…127 (ch. 9, the decision over ch. 7's 0…90).
#[test]
fn kinco_sc_06_notch_n() {
    let mut od = fd3();
    let hz = |n: u64| n * 10 + 100;
    assert_eq!(od.get_unsigned(0x60F9, 3).map(hz), Some(550));
    od.write(0x60F9, 3, &[40]).unwrap();
    assert_eq!(od.get_unsigned(0x60F9, 3).map(hz), Some(500));
    od.write(0x60F9, 3, &[127]).unwrap();
    assert_eq!(od.write(0x60F9, 3, &[128]), Err(AbortCode::VALUE_TOO_HIGH));
    assert_eq!(addr("kinco-fd3").panel("d2.03"), Some((0x60F9, 3)));
}

/// KINCO-SC-07: Speed_Fb_N 60F9h:05 (d2.05) defaults to 25 (600 Hz), range 0…45
/// (100…1000 Hz).
#[test]
fn kinco_sc_07_speed_fb_n() {
    let mut od = fd3();
    let hz = |n: u64| 100 + 20 * n;
    assert_eq!(od.get_unsigned(0x60F9, 5).map(hz), Some(600));
    od.write(0x60F9, 5, &[0]).unwrap();
    assert_eq!(od.get_unsigned(0x60F9, 5).map(hz), Some(100));
    od.write(0x60F9, 5, &[45]).unwrap();
    assert_eq!(od.get_unsigned(0x60F9, 5).map(hz), Some(1000));
    assert_eq!(od.write(0x60F9, 5, &[46]), Err(AbortCode::VALUE_TOO_HIGH));
}

/// KINCO-SC-09: Max_Following_Error_16 2FF0h:0E (d2.16) = 5242; 6065h = 100 × 5242 = 524 200.
#[test]
fn kinco_sc_09_max_following_error() {
    let od = fd3();
    assert_eq!(od.get_unsigned(0x2FF0, 0x0E), Some(5242));
    assert_eq!(od.get_unsigned(0x6065, 0), Some(100 * 5242));
    assert_eq!(addr("kinco-fd3").panel("d2.16"), Some((0x2FF0, 0x0E)));
}

/// KINCO-SC-10: Inertia_Ratio 3040h:0B (tn02) defaults to 30 (ratio 3.0), range 10…500.
#[test]
fn kinco_sc_10_inertia_ratio() {
    let mut od = fd3();
    assert_eq!(od.value(0x3040, 0x0B), Some(Value::Signed(30)));
    assert_eq!(
        od.write(0x3040, 0x0B, &9i16.to_le_bytes()),
        Err(AbortCode::VALUE_TOO_LOW)
    );
    assert_eq!(
        od.write(0x3040, 0x0B, &501i16.to_le_bytes()),
        Err(AbortCode::VALUE_TOO_HIGH)
    );
    assert_eq!(addr("kinco-fd3").panel("tn02"), Some((0x3040, 0x0B)));
}

/// KINCO-SC-11: Safe_Dist 3040h:06 (tn04) defaults to 22 (0.22 rev), at most 40 (0.4 rev).
#[test]
fn kinco_sc_11_safe_dist() {
    let mut od = fd3();
    assert_eq!(od.get_unsigned(0x3040, 6), Some(22));
    assert_eq!(
        devices::KINCO_FD3.entry(0x3040, 6).unwrap().unit,
        "0.01 rev"
    );
    assert_eq!(
        od.write(0x3040, 6, &41u16.to_le_bytes()),
        Err(AbortCode::VALUE_TOO_HIGH)
    );
}

/// KINCO-SC-14: Motor_Num 6410h:01 (d4.01) holds two ASCII characters, the first in the low
/// byte: "JY" = 594Ah, "Y0" = 3059h, "Y1" = 3159h, "Y2" = 3259h; unset "00" = 3030h.
#[test]
fn kinco_sc_14_motor_num() {
    let mut od = fd3();
    assert_eq!(od.get_unsigned(0x6410, 1), Some(0x3030));
    for (code, led) in [
        (b"JY", 0x594A),
        (b"Y0", 0x3059),
        (b"Y1", 0x3159),
        (b"Y2", 0x3259),
    ] {
        od.write(0x6410, 1, code).unwrap();
        assert_eq!(od.get_unsigned(0x6410, 1), Some(led));
    }
    assert_eq!(addr("kinco-fd3").panel("d4.01"), Some((0x6410, 1)));
}

/// Ch. 9: one object, several panel addresses (Store_Data d2.00 = d3.00 = d5.00); the
/// conflicting addresses resolved for ch. 9 (Jog_RPM d3.47, Frequency_Check d3.36,
/// Max_Speed_RPM d2.15, AN_V1/AN_V2 d1.13/d1.14).
#[test]
fn panel_addresses_follow_chapter_9() {
    let a = addr("kinco-fd3");
    let keys: Vec<_> = a.panel_keys(0x2FF0, 1).collect();
    assert_eq!(keys, ["d2.00", "d3.00", "d5.00"]);
    assert_eq!(a.panel("d3.47"), Some((0x2FF0, 0x23)));
    assert_eq!(a.panel("d3.36"), Some((0x2508, 0x08)));
    assert_eq!(a.panel("d2.15"), Some((0x6080, 0)));
    assert_eq!(a.panel("d1.13"), Some((0x2FF0, 0x16)));
    assert_eq!(a.panel("d1.14"), Some((0x2FF0, 0x17)));
    assert_eq!(a.panel("d3.52"), None);
    // Every panel address names an existing entry, in both files.
    for name in ["kinco-fd3", "kinco-cd3"] {
        let d = devices::by_name(name).unwrap();
        for p in addresses_of(name) {
            assert!(d.entry(p.index, p.sub).is_some(), "{name} {}", p.key);
        }
    }
    assert!(
        addr("kinco-cd3").panel("d5.17").is_none(),
        "no CAN on the CD3"
    );
}

fn addresses_of(name: &str) -> &'static [devices::PanelAddress] {
    addr(name).panel
}

/// The register part of the §12.3 examples: 3200h statusword, 3100h controlword, 6F00h target
/// velocity (32 bit: two registers).
#[test]
fn kinco_mb_01_03_registers() {
    let a = addr("kinco-fd3");
    let r = |i, s| a.modbus_register(i, s).map(|r| (r.register, r.words));
    assert_eq!(r(0x6041, 0), Some((0x3200, 1)), "KINCO-MB-01");
    assert_eq!(r(0x6040, 0), Some((0x3100, 1)), "KINCO-MB-02");
    assert_eq!(r(0x60FF, 0), Some((0x6F00, 2)), "KINCO-MB-03");
    for reg in a.modbus {
        let e = devices::KINCO_FD3.entry(reg.index, reg.sub).unwrap();
        assert_eq!(reg.words as u32, e.capacity.div_ceil(2));
    }
}

/// §11 / §10.4: the objects of the printed telegrams have the sizes their commands say
/// (6040h 16 bit, 6060h 8 bit, 607Ah 32 bit) and are PDO-mappable.
#[test]
fn telegram_objects_have_their_printed_sizes() {
    let d = &devices::KINCO_FD3;
    for (i, t) in [
        (0x6040, DataType::Unsigned16),
        (0x6060, DataType::Integer8),
        (0x607A, DataType::Integer32),
        (0x6041, DataType::Unsigned16),
    ] {
        let e = d.entry(i, 0).unwrap();
        assert_eq!(e.data_type, t, "{i:04X}h");
        assert!(e.pdo_mappable);
    }
}

/// The serial ports' objects (§9.5 d5.02, d5.03, d5.15, d5.18, d5.19; §2.1, §12.2): RS232 at
/// RS232_Baudrate 2FE0h, U2BRG 2FE1h at once, RS232_Loop_Enable 6510h:0B; RS485 (the FD3's
/// alone) at RS485_Baudrate 2FE2h, RS485_Protocol 6510h:0C 0 Modbus RTU, 1 the telegrams.
#[test]
fn the_serial_ports_are_device_data() {
    use od::{SerialPort, SerialProtocol};
    for desc in [&devices::KINCO_FD3, &devices::KINCO_CD3] {
        let rs232 = SerialPort::find(desc.serial_ports, "rs232").expect("RS232 on X3");
        assert_eq!(rs232.bit_rate, 0x2FE0);
        assert_eq!(rs232.bit_rate_now, Some(0x2FE1));
        assert_eq!(rs232.loop_enable, Some((0x6510, 0x0B)));
        assert_eq!(rs232.protocol(Some(0)), SerialProtocol::Telegrams);
    }
    assert_eq!(
        SerialPort::find(devices::KINCO_CD3.serial_ports, "rs485"),
        None
    );
    let rs485 = SerialPort::find(devices::KINCO_FD3.serial_ports, "rs485").expect("RS485");
    assert_eq!(rs485.bit_rate, 0x2FE2);
    assert_eq!((rs485.bit_rate_now, rs485.loop_enable), (None, None));
    assert_eq!(rs485.protocol.map(|p| p.object), Some((0x6510, 0x0C)));
    assert_eq!(rs485.protocol(Some(0)), SerialProtocol::ModbusRtu);
    assert_eq!(rs485.protocol(Some(1)), SerialProtocol::Telegrams);
    assert!(devices::CMMP_AS.serial_ports.is_empty());
}
