//! The same blob and inputs give bit-identical outputs, whatever the thread count.

use neusample::{Blob, SamplerKind};
use neusample::{DType, Prepared, Sampler, Vec2, Vec3};
use neusample_host_tests::{rng, small_blob, uniform2};
use rand::RngExt;

/// Every output bit of one evaluation: sample (wo, pdf, pdf_disk) and the pdf of a second
/// direction.
fn evaluate(blob: &Blob<'_>, input: &([f32; 8], Vec3, Vec2, Vec3)) -> [u32; 6] {
    let (phi, wi, u, wo) = input;
    let s = blob.sampler().unwrap();
    let Some(p) = s.prepare(phi, *wi) else {
        return [u32::MAX; 6];
    };
    let (a, b, c, d) = match p.sample(*u) {
        Some(smp) => (
            smp.wo.x.to_bits(),
            smp.wo.y.to_bits(),
            smp.pdf.to_bits(),
            smp.pdf_disk.to_bits(),
        ),
        None => (1, 1, 1, 1),
    };
    [
        a,
        b,
        c,
        d,
        p.pdf(*wo).to_bits(),
        p.pdf_disk(Vec2::new(wo.x, wo.y)).to_bits(),
    ]
}

#[test]
fn outputs_are_bit_identical_across_runs_and_threads() {
    let mut r = rng(77);
    let inputs: Vec<_> = (0..4000)
        .map(|_| {
            let phi: [f32; 8] = std::array::from_fn(|_| r.random::<f32>() * 2.0 - 1.0);
            let wi = Vec3::new(
                r.random::<f32>() - 0.5,
                r.random::<f32>() - 0.5,
                r.random::<f32>(),
            );
            let wo = Vec3::new(
                r.random::<f32>() - 0.5,
                r.random::<f32>() - 0.5,
                r.random::<f32>(),
            );
            (phi, wi, uniform2(&mut r), wo)
        })
        .collect();
    for kind in SamplerKind::ALL {
        for dtype in [DType::F32, DType::F16] {
            let (bytes, _) = small_blob(kind, dtype, 5);
            let blob = Blob::open(&bytes).unwrap();
            let serial: Vec<[u32; 6]> = inputs.iter().map(|i| evaluate(&blob, i)).collect();
            let again: Vec<[u32; 6]> = inputs.iter().map(|i| evaluate(&blob, i)).collect();
            assert_eq!(serial, again, "{kind:?} {dtype:?}: second run differs");
            for threads in [2usize, 3, 8] {
                let chunk = inputs.len().div_ceil(threads);
                let parallel: Vec<[u32; 6]> = std::thread::scope(|sc| {
                    let handles: Vec<_> = inputs
                        .chunks(chunk)
                        .map(|part| {
                            let blob = &blob;
                            sc.spawn(move || {
                                part.iter().map(|i| evaluate(blob, i)).collect::<Vec<_>>()
                            })
                        })
                        .collect();
                    handles
                        .into_iter()
                        .flat_map(|h| h.join().unwrap())
                        .collect()
                });
                assert_eq!(
                    serial, parallel,
                    "{kind:?} {dtype:?}: {threads} threads differ"
                );
            }
        }
    }
}
