//! The sans-IO codec alone: one FHPP cyclic exchange, a 0x17 request writing and reading
//! 4 registers at address 0 (FHPP-MB-03), through `handle_adu`; and the stream framer.

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use modbus::{handle_adu, Exception, Framer, RegisterMap, MAX_ADU_LEN};

/// The FHPP image: 4 output and 4 input registers at address 0.
struct Image {
    outputs: [u16; 4],
    inputs: [u16; 4],
}

impl RegisterMap for Image {
    fn read(&mut self, address: u16, out: &mut [u16]) -> Result<(), Exception> {
        if address != 0 {
            return Err(Exception::IllegalDataAddress);
        }
        let src = self
            .inputs
            .get(..out.len())
            .ok_or(Exception::IllegalDataValue)?;
        out.copy_from_slice(src);
        Ok(())
    }

    fn write(&mut self, address: u16, values: &[u16]) -> Result<(), Exception> {
        if address != 0 {
            return Err(Exception::IllegalDataAddress);
        }
        let dst = self
            .outputs
            .get_mut(..values.len())
            .ok_or(Exception::IllegalDataValue)?;
        dst.copy_from_slice(values);
        self.inputs[0] = self.outputs[0] ^ 0x1000;
        Ok(())
    }
}

const REQUEST: [u8; 25] = [
    0x00, 0x03, 0x00, 0x00, 0x00, 0x13, 0x00, 0x17, 0x00, 0x00, 0x00, 0x04, 0x00, 0x00, 0x00, 0x04,
    0x08, 0x43, 0x03, 0x00, 0x64, 0x00, 0x00, 0x27, 0x10,
];

fn bench(c: &mut Criterion) {
    let mut map = Image {
        outputs: [0; 4],
        inputs: [0x5383, 0x0064, 0, 0],
    };
    let mut out = [0u8; MAX_ADU_LEN];
    assert_eq!(handle_adu(&REQUEST, &mut map, &mut out), Ok(17));
    let mut g = c.benchmark_group("modbus");
    g.throughput(Throughput::Elements(1));
    g.bench_function("handle_adu_0x17_4_registers", |b| {
        b.iter(|| handle_adu(black_box(&REQUEST), &mut map, &mut out).map(black_box))
    });
    let mut framer = Framer::new();
    g.bench_function("frame_and_handle_0x17", |b| {
        b.iter(|| {
            framer.push(black_box(&REQUEST));
            if let Ok(Some(adu)) = framer.next_adu() {
                let _ = black_box(handle_adu(adu, &mut map, &mut out));
            }
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
