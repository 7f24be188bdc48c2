//! The exact trace's roofline on this processor: how long one f64 lane of a vector square root,
//! division and fused multiply-add takes when the unit is kept busy (independent chains, so
//! throughput, not latency), in the widest vector set the trace's lanes use here (AVX-512 or
//! AVX2). Criterion's throughput line reads "elements/s" = lanes per second; its reciprocal is
//! the time per lane that README's roofline arithmetic multiplies by each surface's count of
//! square roots and divisions. `sqrt_then_div` is a square root and a division per step: if it
//! takes the sum of the two alone, they share one unit, as the arithmetic assumes.
//!
//! On a processor with neither set the benchmark measures nothing (the trace's portable path
//! has no roofline of this kind to compare with).
//!
//! `roofline_memory` is the other side: the bytes the 1M-ray trace reads and writes, moved
//! without the arithmetic.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use lensbake::trace::Outcome;

/// Vector operations per chain and iteration of a measurement.
const STEPS: usize = 4096;
/// Independent chains: more than a square root's latency over its issue interval, so the unit,
/// not the wait for a result, bounds the loop.
const CHAINS: usize = 8;

#[cfg(target_arch = "x86_64")]
mod kernels {
    use super::{CHAINS, STEPS};
    use std::arch::x86_64::*;

    /// Each chain's value goes through `step` STEPS times; returns the chains' sum so nothing is
    /// optimised away.
    macro_rules! chained {
        ($name:ident, $features:literal, $vector:ty, $splat:ident, $add:ident, $store:ident,
         $lanes:expr, |$x:ident| $step:expr) => {
            #[target_feature(enable = $features)]
            pub unsafe fn $name(start: f64) -> f64 {
                let mut chains: [$vector; CHAINS] =
                    std::array::from_fn(|k| $splat(start + k as f64 * 0.001));
                for _ in 0..STEPS {
                    for $x in chains.iter_mut() {
                        *$x = $step;
                    }
                }
                let mut sum = $splat(0.0);
                for c in chains {
                    sum = $add(sum, c);
                }
                let mut lanes = [0.0; $lanes];
                // SAFETY: `lanes` holds one vector.
                unsafe { $store(lanes.as_mut_ptr(), sum) };
                lanes.iter().sum()
            }
        };
    }

    // Square roots of square roots tend to 1; divisions by a number just above 1 and
    // multiply-adds that halve and add 1 stay finite and normal for any number of steps.
    chained!(
        sqrt_avx2,
        "avx2,fma",
        __m256d,
        _mm256_set1_pd,
        _mm256_add_pd,
        _mm256_storeu_pd,
        4,
        |x| _mm256_sqrt_pd(*x)
    );
    chained!(
        div_avx2,
        "avx2,fma",
        __m256d,
        _mm256_set1_pd,
        _mm256_add_pd,
        _mm256_storeu_pd,
        4,
        |x| _mm256_div_pd(*x, _mm256_set1_pd(1.000_000_1))
    );
    chained!(
        sqrt_div_avx2,
        "avx2,fma",
        __m256d,
        _mm256_set1_pd,
        _mm256_add_pd,
        _mm256_storeu_pd,
        4,
        |x| _mm256_div_pd(_mm256_sqrt_pd(*x), _mm256_set1_pd(1.000_000_1))
    );
    chained!(
        fma_avx2,
        "avx2,fma",
        __m256d,
        _mm256_set1_pd,
        _mm256_add_pd,
        _mm256_storeu_pd,
        4,
        |x| _mm256_fmadd_pd(*x, _mm256_set1_pd(0.5), _mm256_set1_pd(1.0))
    );
    chained!(
        sqrt_avx512,
        "avx512f",
        __m512d,
        _mm512_set1_pd,
        _mm512_add_pd,
        _mm512_storeu_pd,
        8,
        |x| _mm512_sqrt_pd(*x)
    );
    chained!(
        div_avx512,
        "avx512f",
        __m512d,
        _mm512_set1_pd,
        _mm512_add_pd,
        _mm512_storeu_pd,
        8,
        |x| _mm512_div_pd(*x, _mm512_set1_pd(1.000_000_1))
    );
    chained!(
        sqrt_div_avx512,
        "avx512f",
        __m512d,
        _mm512_set1_pd,
        _mm512_add_pd,
        _mm512_storeu_pd,
        8,
        |x| _mm512_div_pd(_mm512_sqrt_pd(*x), _mm512_set1_pd(1.000_000_1))
    );
    chained!(
        fma_avx512,
        "avx512f",
        __m512d,
        _mm512_set1_pd,
        _mm512_add_pd,
        _mm512_storeu_pd,
        8,
        |x| _mm512_fmadd_pd(*x, _mm512_set1_pd(0.5), _mm512_set1_pd(1.0))
    );

    /// The kernels of the widest set this processor has, with its lanes per vector and name.
    pub type Kernel = unsafe fn(f64) -> f64;
    /// Each measurement's name and kernel.
    pub type Named = [(&'static str, Kernel); 4];
    pub fn widest() -> Option<(&'static str, usize, Named)> {
        if is_x86_feature_detected!("avx512f") {
            Some((
                "avx512",
                8,
                [
                    ("sqrt", sqrt_avx512),
                    ("div", div_avx512),
                    ("sqrt_then_div", sqrt_div_avx512),
                    ("fma", fma_avx512),
                ],
            ))
        } else if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
            Some((
                "avx2",
                4,
                [
                    ("sqrt", sqrt_avx2),
                    ("div", div_avx2),
                    ("sqrt_then_div", sqrt_div_avx2),
                    ("fma", fma_avx2),
                ],
            ))
        } else {
            None
        }
    }
}

fn roofline(c: &mut Criterion) {
    #[cfg(target_arch = "x86_64")]
    if let Some((set, lanes, kernels)) = kernels::widest() {
        let mut group = c.benchmark_group(format!("roofline_{set}"));
        group.throughput(Throughput::Elements((STEPS * CHAINS * lanes) as u64));
        for (name, kernel) in kernels {
            group.bench_function(name, |b| {
                // SAFETY: `widest` offers only kernels of sets this processor has.
                b.iter(|| unsafe { kernel(std::hint::black_box(1.5)) })
            });
        }
        group.finish();
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = c;
}

/// Rays of the 1M-ray trace (`lensbake bench trace --rays 1000000`) whose memory traffic
/// `memory_roofline` moves.
const TRAFFIC_RAYS: usize = 1_000_000;

/// The memory side of the roofline: the bytes the 1M-ray trace reads and writes, moved with no
/// arithmetic. Each ray's start (six f64 columns, 48 bytes) is read and its result (six f64
/// columns and an [`Outcome`], 64 bytes) written into storage reused from the last call, as
/// `Tracer::trace_batch_into` does. "elements/s" = rays per second; the trace cannot run faster
/// than this however fast its arithmetic.
fn memory_roofline(c: &mut Criterion) {
    const {
        assert!(
            size_of::<Outcome>() == 16,
            "README counts a 16-byte outcome per ray"
        )
    };
    let rays: [Vec<f64>; 6] = std::array::from_fn(|k| vec![k as f64; TRAFFIC_RAYS]);
    let mut ended: [Vec<f64>; 6] = std::array::from_fn(|_| vec![0.0; TRAFFIC_RAYS]);
    let mut outcomes = vec![Outcome::Ok; TRAFFIC_RAYS];
    let mut group = c.benchmark_group("roofline_memory");
    group.throughput(Throughput::Elements(TRAFFIC_RAYS as u64));
    group.sample_size(20);
    group.bench_function("trace_traffic_1m_rays", |b| {
        b.iter(|| {
            for (to, from) in ended.iter_mut().zip(&rays) {
                to.copy_from_slice(std::hint::black_box(from));
            }
            outcomes.fill(std::hint::black_box(Outcome::Vignetted { surface: 1 }));
            std::hint::black_box((&ended, &outcomes));
        })
    });
    group.finish();
}

criterion_group!(benches, roofline, memory_roofline);
criterion_main!(benches);
