//! The SII image of the CMMP-AS, read back the way the masters read it (the ESC reference kept
//! beside the project, §3).
//!
//! The category walker, the PDO size computation and the KickCAT read rule below are written
//! here, independently of `ethercat::sii`, after SOEM 1.4 `ecx_siifind` / `ecx_siiPDO` and
//! KickCAT `Bus::fetchEeprom`. ethercrab's SII parser is not public (`mod eeprom;` is private in
//! ethercrab 0.7.1 `src/lib.rs`; SII is read only through a live `MainDevice`), so it cannot be
//! run against the image offline; its strict decoding rules are checked by hand instead.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use ethercat::sii::{
    self, build_sii, category, crc8, read_into, read_word, set_station_alias, SiiConfig, SiiError,
    DEFAULT_IMAGE_SIZE,
};

fn cmmp() -> &'static od::DeviceDescription {
    devices::by_name("cmmp-as").expect("cmmp-as personality")
}

fn image() -> (Vec<u8>, usize) {
    let mut buf = vec![0u8; DEFAULT_IMAGE_SIZE];
    let used = build_sii(
        cmmp(),
        &SiiConfig::from_description(&devices::CMMP_AS),
        &mut buf,
    )
    .expect("image builds");
    (buf, used)
}

fn w(img: &[u8], a: u16) -> u16 {
    u16::from_le_bytes([img[a as usize * 2], img[a as usize * 2 + 1]])
}

fn dw(img: &[u8], a: u16) -> u32 {
    u32::from(w(img, a)) | (u32::from(w(img, a + 1)) << 16)
}

/// SOEM's `ecx_siifind`: byte address of the category's length word, 0 if absent.
fn siifind(img: &[u8], cat: u16) -> usize {
    let mut a: usize = 0x40 << 1;
    let mut p = u16::from_le_bytes([img[a], img[a + 1]]);
    a += 2;
    while p != cat && p != 0xFFFF {
        let len = u16::from_le_bytes([img[a], img[a + 1]]) as usize;
        a += len * 2 + 2;
        if a >= img.len() - 1 {
            return 0;
        }
        p = u16::from_le_bytes([img[a], img[a + 1]]);
        a += 2;
    }
    if p != cat {
        0
    } else {
        a
    }
}

/// All categories in order: (type, length in words, data).
fn walk(img: &[u8]) -> (Vec<(u16, u16, Vec<u8>)>, usize) {
    let mut out = vec![];
    let mut a = 0x40usize;
    loop {
        let t = w(img, a as u16);
        if t == 0xFFFF {
            return (out, a);
        }
        let len = w(img, a as u16 + 1);
        let data = img[(a + 2) * 2..(a + 2 + len as usize) * 2].to_vec();
        out.push((t, len, data));
        a += 2 + len as usize;
        assert!(a * 2 < img.len(), "walked off the image");
    }
}

fn strings(img: &[u8]) -> Vec<String> {
    let a = siifind(img, category::STRINGS);
    assert_ne!(a, 0);
    let data = &img[a + 2..];
    let n = data[0] as usize;
    let mut pos = 1;
    let mut v = vec![];
    for _ in 0..n {
        let len = data[pos] as usize;
        v.push(String::from_utf8(data[pos + 1..pos + 1 + len].to_vec()).unwrap());
        pos += 1 + len;
    }
    v
}

#[derive(Debug, PartialEq)]
struct Pdo {
    index: u16,
    sm: u8,
    name: u8,
    flags: u16,
    entries: Vec<(u16, u8, u8, u8, u8)>, // index, sub, name, data type, bits
}

fn pdos(img: &[u8], cat: u16) -> Vec<Pdo> {
    let a = siifind(img, cat);
    assert_ne!(a, 0, "category {cat} missing");
    let len = u16::from_le_bytes([img[a], img[a + 1]]) as usize * 2;
    let data = &img[a + 2..a + 2 + len];
    let mut p = 0;
    let mut v = vec![];
    while p < data.len() {
        let n = data[p + 2] as usize;
        let mut pdo = Pdo {
            index: u16::from_le_bytes([data[p], data[p + 1]]),
            sm: data[p + 3],
            name: data[p + 5],
            flags: u16::from_le_bytes([data[p + 6], data[p + 7]]),
            entries: vec![],
        };
        p += 8;
        for _ in 0..n {
            let e = &data[p..p + 8];
            pdo.entries
                .push((u16::from_le_bytes([e[0], e[1]]), e[2], e[3], e[4], e[5]));
            p += 8;
        }
        v.push(pdo);
    }
    assert_eq!(p, data.len(), "PDO category length matches its PDOs");
    v
}

#[test]
fn crc8_matches_the_akd_vectors() {
    // the ESC reference kept beside the project, §3.2 (ethercrab's tests on an AKD dump).
    let a = [0x09, 0, 0, 0x08, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0];
    assert_eq!(crc8(&a), 0x10);
    let b = [0x09, 0, 0, 0x08, 0, 0, 0, 0, 0xCD, 0xAB, 0, 0, 0, 0];
    assert_eq!(crc8(&b), 0x04);
    // The catalogue check value of this parameter set (poly 0x07, init 0xFF, no reflection).
    assert_eq!(crc8(b"123456789"), 0xFB);
}

#[test]
fn header_words() {
    let (img, used) = image();
    let d = cmmp();
    assert_eq!(img.len(), 2048);
    assert!(used < 4096, "below SOEM's SII cache");
    assert_eq!(w(&img, 0x00), 0x0005);
    assert_eq!(w(&img, 0x04), 0, "station alias");
    assert_eq!(dw(&img, 0x08), 0x0000_001D, "vendor Festo");
    assert_eq!(dw(&img, 0x08), d.vendor_id);
    assert_eq!(dw(&img, 0x0A), 0x0018_C375);
    assert_eq!(dw(&img, 0x0A), d.product_code);
    assert_eq!(dw(&img, 0x0C), 0x0004_0000);
    assert_eq!(dw(&img, 0x0C), d.revision);
    assert_eq!(dw(&img, 0x0E), 0, "serial");
    for a in 0x10..=0x17 {
        assert_eq!(w(&img, a), 0, "word {a:#x}: delays, bootstrap mailbox");
    }
    assert_eq!(w(&img, 0x18), 0x1000);
    assert_eq!(w(&img, 0x19), 0x0080);
    assert_eq!(w(&img, 0x1A), 0x1080);
    assert_eq!(w(&img, 0x1B), 0x0080);
    assert_eq!(w(&img, 0x1C), 0x0004, "CoE only");
    for a in 0x1D..=0x3D {
        assert_eq!(w(&img, a), 0, "reserved word {a:#x}");
    }
    assert_eq!(w(&img, 0x3E), 15, "2 KiB = 16 kbit - 1");
    assert_eq!(w(&img, 0x3F), 1);
}

#[test]
fn checksum_over_words_0_to_6() {
    let (mut img, _) = image();
    // Words 0-6 are 05 00 00 .. 00: CRC 0x48 (computed independently).
    let mut area = [0u8; 14];
    area[0] = 0x05;
    assert_eq!(w(&img, 7), u16::from(crc8(&area)));
    assert_eq!(w(&img, 7), 0x0048);
    set_station_alias(&mut img, 0xABCD).unwrap();
    assert_eq!(w(&img, 4), 0xABCD);
    area[8] = 0xCD;
    area[9] = 0xAB;
    assert_eq!(w(&img, 7), u16::from(crc8(&area)));
    // An alias in the config gives the same image as setting it afterwards.
    let mut buf = vec![0u8; DEFAULT_IMAGE_SIZE];
    let cfg = SiiConfig {
        station_alias: 0xABCD,
        ..SiiConfig::from_description(&devices::CMMP_AS)
    };
    build_sii(cmmp(), &cfg, &mut buf).unwrap();
    assert_eq!(buf, img);
}

#[test]
fn categories_in_order_with_consistent_lengths() {
    let (img, used) = image();
    let (cats, end) = walk(&img);
    let kinds: Vec<u16> = cats.iter().map(|c| c.0).collect();
    assert_eq!(
        kinds,
        [
            category::STRINGS,
            category::GENERAL,
            category::FMMU,
            category::SYNC_M,
            category::TX_PDO,
            category::RX_PDO
        ]
    );
    // END marker right where build_sii stopped; erased EEPROM after it.
    assert_eq!(w(&img, end as u16), 0xFFFF);
    assert_eq!((end + 1) * 2, used);
    assert!(img[used..].iter().all(|&b| b == 0xFF));
    // Lengths: General 16 words, FMMU 2, SyncM 4 × 4.
    assert_eq!(cats[1].1, 16);
    assert_eq!(cats[2].1, 2);
    assert_eq!(cats[3].1, 16);
    // Strings: the count byte and the length-prefixed strings fill the category (+ pad).
    let s = &cats[0].2;
    let mut pos = 1;
    for _ in 0..s[0] {
        pos += 1 + s[pos] as usize;
    }
    assert_eq!(pos.div_ceil(2), cats[0].1 as usize);
    // SOEM finds each category.
    for k in kinds {
        assert_ne!(siifind(&img, k), 0);
    }
    assert_eq!(siifind(&img, category::DC), 0);
    // The library's own walker agrees.
    let lib: Vec<(u16, usize)> = sii::categories(&img)
        .map(|c| (c.kind, c.data.len()))
        .collect();
    let ours: Vec<(u16, usize)> = cats.iter().map(|c| (c.0, c.2.len())).collect();
    assert_eq!(lib, ours);
}

#[test]
fn no_ffff_word_before_end_kickcat_reads_it_all() {
    let (img, used) = image();
    // KickCAT Bus::fetchEeprom: 32-bit reads from word 0; stops at the first dword with a
    // 0xFFFF half-word after the first 32 dwords.
    let mut got = vec![];
    let mut addr = 0u32;
    loop {
        let mut d = [0u8; 4];
        read_into(&img, addr, &mut d);
        got.extend_from_slice(&d);
        let lo = u16::from_le_bytes([d[0], d[1]]);
        let hi = u16::from_le_bytes([d[2], d[3]]);
        if addr / 2 >= 32 && (lo == 0xFFFF || hi == 0xFFFF) {
            break;
        }
        addr += 2;
    }
    assert!(got.len() >= used, "KickCAT read the whole image");
    assert_eq!(&got[..used], &img[..used]);
}

#[test]
fn general_category() {
    let (img, _) = image();
    let a = siifind(&img, category::GENERAL) + 2;
    let g = &img[a..a + 32];
    let s = strings(&img);
    assert_eq!(s[g[0] as usize - 1], "Festo Electric-Drives", "group");
    assert_eq!(g[1], 0, "no image");
    assert_eq!(s[g[2] as usize - 1], "CMMP-AS-C2-3A-M3", "order");
    assert_eq!(s[g[3] as usize - 1], "CMMP-AS-C2-3A-M3", "name");
    assert_eq!(g[5], 0x0F, "CoE: SDO, SDO info, PDO assign, PDO config");
    assert_eq!(g[5] & 0xC0, 0, "ethercrab rejects CoE bits 6-7");
    assert_eq!(&g[6..9], &[0, 0, 0], "FoE, EoE, SoE");
    assert_eq!(g[9], 1, "one CiA 402 axis");
    assert_eq!(g[11] & 0xE0, 0, "ethercrab rejects flag bits 5-7");
    assert_eq!(i16::from_le_bytes([g[12], g[13]]), 0);
    assert_eq!(&g[14..16], &[0, 0]);
    assert_eq!(u16::from_le_bytes([g[16], g[17]]), 0x0011, "two MII ports");
    assert!(g[18..].iter().all(|&b| b == 0));
}

#[test]
fn string_table() {
    let (img, _) = image();
    let s = strings(&img);
    assert_eq!(s[0], "CMMP-AS-C2-3A-M3", "SOEM's slave name is string 1");
    assert!(s[0].len() <= 40);
    for want in [
        "Festo Electric-Drives",
        "Outputs",
        "Inputs",
        "RxPDO 2",
        "TxPDO 4",
        "statusword",
        "controlword",
        "modes_of_operation",
        "position_actual_value",
        "target_velocity",
    ] {
        assert!(s.iter().any(|x| x == want), "{want} in {s:?}");
    }
    let mut sorted = s.clone();
    sorted.sort();
    sorted.dedup();
    assert_eq!(sorted.len(), s.len(), "strings are de-duplicated");
    assert!(s.iter().all(|x| x.is_ascii()));
    assert_eq!(
        sii::string_at(&[2, 1, b'a', 2, b'b', b'c'], 2),
        Some(&b"bc"[..])
    );
}

#[test]
fn fmmu_and_sync_managers() {
    let (img, _) = image();
    let a = siifind(&img, category::FMMU) + 2;
    assert_eq!(&img[a..a + 4], &[1, 2, 3, 0]);

    let a = siifind(&img, category::SYNC_M) + 2;
    let sm = |n: usize| {
        let e = &img[a + 8 * n..a + 8 * n + 8];
        (
            u16::from_le_bytes([e[0], e[1]]),
            u16::from_le_bytes([e[2], e[3]]),
            e[4],
            e[5],
            e[6],
            e[7],
        )
    };
    assert_eq!(sm(0), (0x1000, 0x80, 0x26, 0, 1, 1), "SM0 mailbox out");
    assert_eq!(sm(1), (0x1080, 0x80, 0x22, 0, 1, 2), "SM1 mailbox in");
    assert_eq!(
        sm(2),
        (0x1100, 2, 0x64, 0, 1, 3),
        "SM2 outputs: controlword"
    );
    assert_eq!(sm(3), (0x1180, 2, 0x20, 0, 1, 4), "SM3 inputs: statusword");
    for n in 0..4 {
        let (_, _, control, _, enable, kind) = sm(n);
        // ethercrab's strict decoding: mode 00/10, direction 00/01, enable bits 0-3, type 0-4.
        assert!(matches!(control & 3, 0 | 2));
        assert!(matches!((control >> 2) & 3, 0 | 1));
        assert_eq!(enable & 0xF0, 0);
        assert!(kind <= 4);
    }
    // Words 0x18-0x1B agree with SM0/SM1 (ethercrab takes the length from the words).
    assert_eq!((w(&img, 0x18), w(&img, 0x19)), (sm(0).0, sm(0).1));
    assert_eq!((w(&img, 0x1A), w(&img, 0x1B)), (sm(1).0, sm(1).1));
}

#[test]
fn default_pdo_mappings() {
    let (img, _) = image();
    let s = strings(&img);
    let name = |i: u8| s[i as usize - 1].as_str();

    let tx = pdos(&img, category::TX_PDO);
    assert_eq!(
        tx.iter().map(|p| p.index).collect::<Vec<_>>(),
        [0x1A00, 0x1A01, 0x1A02, 0x1A03]
    );
    assert_eq!(tx[0].sm, 3);
    assert_eq!(tx[0].flags, 0x0002);
    assert_eq!(name(tx[0].name), "Inputs");
    assert_eq!(tx[0].entries.len(), 1);
    let (i, sub, n, dt, bits) = tx[0].entries[0];
    assert_eq!((i, sub, dt, bits), (0x6041, 0, 0x06, 16));
    assert_eq!(name(n), "statusword");
    assert!(tx[1..].iter().all(|p| p.sm == 0xFF && p.flags == 0));
    assert_eq!(name(tx[1].name), "TxPDO 2");
    let e: Vec<_> = tx[1].entries.iter().map(|e| (e.0, e.1, e.3, e.4)).collect();
    assert_eq!(e, [(0x6041, 0, 0x06, 16), (0x6061, 0, 0x02, 8)]);
    let e: Vec<_> = tx[2].entries.iter().map(|e| (e.0, e.1, e.3, e.4)).collect();
    assert_eq!(e, [(0x6041, 0, 0x06, 16), (0x6064, 0, 0x04, 32)]);
    let e: Vec<_> = tx[3].entries.iter().map(|e| (e.0, e.1, e.3, e.4)).collect();
    assert_eq!(e, [(0x6041, 0, 0x06, 16), (0x606C, 0, 0x04, 32)]);

    let rx = pdos(&img, category::RX_PDO);
    assert_eq!(
        rx.iter().map(|p| p.index).collect::<Vec<_>>(),
        [0x1600, 0x1601, 0x1602, 0x1603]
    );
    assert_eq!(rx[0].sm, 2);
    assert_eq!(name(rx[0].name), "Outputs");
    let (i, sub, n, dt, bits) = rx[0].entries[0];
    assert_eq!((i, sub, dt, bits), (0x6040, 0, 0x06, 16));
    assert_eq!(name(n), "controlword");
    let e: Vec<_> = rx[1].entries.iter().map(|e| (e.0, e.1, e.3, e.4)).collect();
    assert_eq!(e, [(0x6040, 0, 0x06, 16), (0x6060, 0, 0x02, 8)]);
    let e: Vec<_> = rx[2].entries.iter().map(|e| (e.0, e.1, e.3, e.4)).collect();
    assert_eq!(e, [(0x6040, 0, 0x06, 16), (0x607A, 0, 0x04, 32)]);
    let e: Vec<_> = rx[3].entries.iter().map(|e| (e.0, e.1, e.3, e.4)).collect();
    assert_eq!(e, [(0x6040, 0, 0x06, 16), (0x60FF, 0, 0x04, 32)]);
    assert!(rx[1..].iter().all(|p| p.sm == 0xFF));
    // Every entry's bit length agrees with the mapped object's type.
    for p in tx.iter().chain(&rx) {
        for &(i, sub, _, _, bits) in &p.entries {
            let e = cmmp().entry(i, sub).expect("mapped entry exists");
            assert_eq!(u32::from(bits), e.bit_len(), "{i:04X}:{sub}");
        }
    }
}

/// SOEM 1.4 `ecx_siiPDO`, word counter `c` and all, giving the bits per SM.
fn soem_sii_pdo(img: &[u8], t: u16) -> [u32; 8] {
    let mut smbits = [0u32; 8];
    let start = siifind(img, t);
    assert_ne!(start, 0);
    let byte = |a: usize| img[a] as u32;
    let mut a = start;
    let length = byte(a) | (byte(a + 1) << 8);
    a += 2;
    let mut c = 1u32;
    loop {
        a += 2; // index
        c += 1;
        let e = byte(a);
        a += 1;
        let sm = byte(a);
        a += 1;
        a += 4;
        c += 2;
        if sm < 8 {
            let mut bits = 0;
            for _ in 0..e {
                c += 4;
                a += 5;
                bits += byte(a);
                a += 1;
                a += 2;
            }
            smbits[sm as usize] += bits;
            c += 1;
        } else {
            c += 4 * e;
            a += 8 * e as usize;
            c += 1;
        }
        if c >= length {
            break;
        }
    }
    smbits
}

#[test]
fn soem_fallback_sizes_match_the_sync_managers() {
    let (img, _) = image();
    assert_eq!(soem_sii_pdo(&img, category::RX_PDO)[2], 16);
    assert_eq!(soem_sii_pdo(&img, category::TX_PDO)[3], 16);
}

#[test]
fn other_assignments_resize_sm2_and_sm3() {
    let cfg = SiiConfig {
        rx_assigned: &[0x1601, 0x1602],
        tx_assigned: &[0x1A02, 0x1A03],
        ..SiiConfig::from_description(&devices::CMMP_AS)
    };
    let mut img = vec![0u8; DEFAULT_IMAGE_SIZE];
    build_sii(cmmp(), &cfg, &mut img).unwrap();
    let a = siifind(&img, category::SYNC_M) + 2;
    assert_eq!(
        w(&img, ((a + 16 + 2) / 2) as u16),
        3 + 6,
        "SM2: 24 + 48 bits"
    );
    assert_eq!(
        w(&img, ((a + 24 + 2) / 2) as u16),
        6 + 6,
        "SM3: 48 + 48 bits"
    );
    let rx = pdos(&img, category::RX_PDO);
    let sms: Vec<u8> = rx.iter().map(|p| p.sm).collect();
    assert_eq!(sms, [0xFF, 2, 2, 0xFF]);
    assert_eq!(soem_sii_pdo(&img, category::RX_PDO)[2], 72);
    assert_eq!(soem_sii_pdo(&img, category::TX_PDO)[3], 96);
    let s = strings(&img);
    assert_eq!(s[rx[0].name as usize - 1], "RxPDO 1");
    assert_eq!(s[rx[1].name as usize - 1], "Outputs");
}

#[test]
fn esc_register_reads() {
    let (img, _) = image();
    assert_eq!(read_word(&img, 0x08), 0x001D);
    assert_eq!(read_word(&img, 0x0A), 0xC375);
    assert_eq!(read_word(&img, 0x0B), 0x0018);
    assert_eq!(read_word(&img, 5000), 0xFFFF, "beyond the image: erased");
    let mut d = [0u8; 8];
    read_into(&img, 0x08, &mut d);
    assert_eq!(d, [0x1D, 0, 0, 0, 0x75, 0xC3, 0x18, 0]);
    let mut d = [0u8; 4];
    read_into(&img, 0x3FF, &mut d);
    assert_eq!(d, [0xFF; 4], "last word (erased) then beyond");
    let mut m = img.clone();
    sii::write_word(&mut m, 0x0E, 0x1234).unwrap();
    assert_eq!(read_word(&m, 0x0E), 0x1234);
    assert_eq!(
        sii::write_word(&mut m, 0x400, 0),
        Err(SiiError::BufferTooSmall)
    );
}

#[test]
fn errors() {
    let mut small = vec![0u8; 256];
    assert_eq!(
        build_sii(
            cmmp(),
            &SiiConfig::from_description(&devices::CMMP_AS),
            &mut small
        ),
        Err(SiiError::BufferTooSmall)
    );
    let mut odd = vec![0u8; 1000];
    assert_eq!(
        build_sii(
            cmmp(),
            &SiiConfig::from_description(&devices::CMMP_AS),
            &mut odd
        ),
        Err(SiiError::BufferTooSmall)
    );
    let mut buf = vec![0u8; DEFAULT_IMAGE_SIZE];
    let cfg = SiiConfig {
        rx_assigned: &[0x1604],
        ..SiiConfig::from_description(&devices::CMMP_AS)
    };
    assert_eq!(
        build_sii(cmmp(), &cfg, &mut buf),
        Err(SiiError::PdoNotFound(0x1604))
    );
    let cfg = SiiConfig {
        inputs_start: 0x1102,
        ..SiiConfig::from_description(&devices::CMMP_AS)
    };
    assert_eq!(build_sii(cmmp(), &cfg, &mut buf), Err(SiiError::SmOverlap));
    // A 4 KiB EEPROM: size word 31, same content.
    let mut big = vec![0u8; 4096];
    let used = build_sii(
        cmmp(),
        &SiiConfig::from_description(&devices::CMMP_AS),
        &mut big,
    )
    .unwrap();
    assert_eq!(w(&big, 0x3E), 31);
    let (img, used2) = image();
    assert_eq!(used, used2);
    assert_eq!(big[0x80..used], img[0x80..used]);
}

#[test]
fn every_personality_builds() {
    for d in devices::ALL {
        let has = |r: std::ops::RangeInclusive<u16>| d.objects.iter().any(|o| r.contains(&o.index));
        let cfg = SiiConfig {
            rx_assigned: if has(0x1600..=0x1600) { &[0x1600] } else { &[] },
            tx_assigned: if has(0x1A00..=0x1A00) { &[0x1A00] } else { &[] },
            ..SiiConfig::from_description(&devices::CMMP_AS)
        };
        let mut buf = vec![0u8; DEFAULT_IMAGE_SIZE];
        let used = build_sii(d, &cfg, &mut buf).unwrap_or_else(|e| panic!("{}: {e:?}", d.name));
        assert_eq!(read_word(&buf, (used / 2 - 1) as u32), 0xFFFF);
        assert_eq!(dw(&buf, 8), d.vendor_id);
    }
}
