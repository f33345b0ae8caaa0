//! Bytes into the CMMP-AS CI terminal (RS232 debug console, CMMP-AS §3.2.3) over its
//! dictionary: no panic, and every answer is one line that starts with `=` or `!`.
#![no_main]

use drive::vendors::festo_cmmp_as::ci_terminal::CiTerminal;
use libfuzzer_sys::fuzz_target;
use od::ObjectDictionary;

fuzz_target!(|data: &[u8]| {
    let desc = &devices::CMMP_AS;
    let Ok(mut od) = ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]) else {
        return;
    };
    let mut term = CiTerminal::default();
    for &byte in data {
        if let Some(reply) = term.on_byte(byte, &mut od) {
            let text = reply.as_bytes();
            assert!(
                matches!(text.first(), Some(b'=') | Some(b'!')),
                "answer {text:?}"
            );
        }
    }
});
