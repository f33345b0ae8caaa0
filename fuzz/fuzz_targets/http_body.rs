//! Any bytes as the JSON body of a web API request (web/api.rs and the other handlers'
//! bodies), through the same parse and the same checks the handlers run before they touch
//! the cell (`web::api::parse_body`, then each body's checks): no panic, a refusal is a 4xx.
#![no_main]

use drivetwin::cell::wire_faults::FaultSpec;
use drivetwin::vendors::festo_cmmo_st::web_server::{DeviceControlBody, SaveBody};
use drivetwin::vendors::kinco::panel_page::KeyBody;
use drivetwin::web::api::{
    parse_body, ApiError, DisturbBody, InputsBody, LoadBody, SupplyBody, WriteBody,
};
use drivetwin::web::motion::{JogBody, MoveBody};
use drivetwin::web::physics::{AmbientBody, EncoderBody, SwitchBody, ThermalBody};
use drivetwin::web::wire::TraceBody;
use libfuzzer_sys::fuzz_target;

fn refused(r: Result<(), ApiError>) {
    if let Err(e) = r {
        assert!(e.status.is_client_error(), "a bad body is a 4xx: {e:?}");
    }
}

/// The input: byte 0 chooses the route (and for an object write, byte 1 the entry of the
/// CMMP-AS it is for), the rest is the body.
fn run(data: &[u8]) {
    let [route, pick, body @ ..] = data else {
        return;
    };
    match route % 16 {
        0 => refused(parse_body::<DisturbBody>(body).and_then(|b| b.check())),
        1 => {
            let entries: Vec<_> = devices::CMMP_AS.entries().collect();
            let Some(e) = entries.get(usize::from(*pick) * entries.len() / 256) else {
                return;
            };
            refused(parse_body::<WriteBody>(body).and_then(|b| b.bytes(e).map(drop)));
        }
        2 => refused(parse_body::<InputsBody>(body).map(drop)),
        3 => refused(parse_body::<SupplyBody>(body).and_then(|b| b.millivolts().map(drop))),
        4 => refused(parse_body::<LoadBody>(body).and_then(|b| b.check())),
        5 => refused(parse_body::<JogBody>(body).map(drop)),
        6 => refused(parse_body::<MoveBody>(body).map(drop)),
        7 => refused(parse_body::<SaveBody>(body).and_then(|b| b.enabled_by().map(drop))),
        8 => refused(parse_body::<DeviceControlBody>(body).map(drop)),
        9 => refused(parse_body::<KeyBody>(body).map(drop)),
        10 => refused(parse_body::<TraceBody>(body).map(drop)),
        11 => refused(parse_body::<AmbientBody>(body).and_then(|b| b.check())),
        12 => refused(parse_body::<ThermalBody>(body).and_then(|b| b.data().map(drop))),
        13 => refused(parse_body::<EncoderBody>(body).and_then(|b| b.fault().map(drop))),
        14 => refused(parse_body::<SwitchBody>(body).map(drop)),
        _ => {
            // A wire fault: parsed, then turned into the fault the cell would inject.
            if let Ok(spec) = parse_body::<FaultSpec>(body) {
                let _ = spec.to_fault();
            }
        }
    }
}

fuzz_target!(|data: &[u8]| run(data));
