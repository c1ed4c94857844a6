//! `JᵀJ` kernels compared on the shapes the solver meets (`docs/performance.md`): nalgebra's
//! `tr_mul` (one dot product per element), `gemm` on a transposed view (the `matrixmultiply`
//! kernel, what `calibration::normal_equations` uses) and `gemm` on a transposed copy. Best of
//! 7 runs per kernel.
//!
//! `cargo run --release --example gram_kernels`
use nalgebra::{DMatrix, DMatrixView};
use std::time::Instant;
fn main() {
    for (m, p) in [(12usize, 64usize), (192, 64), (384, 64), (2400, 64)] {
        let a = DMatrix::from_fn(m, p, |i, j| ((i * 31 + j * 17) % 97) as f64 / 97.0 - 0.5);
        let reps = (200_000_000 / (2 * m * p * p)).max(10);
        let mut best = [f64::INFINITY; 3];
        for _ in 0..7 {
            let t = Instant::now();
            let mut acc = DMatrix::<f64>::zeros(p, p);
            for _ in 0..reps {
                acc += a.tr_mul(&a);
            }
            best[0] = best[0].min(t.elapsed().as_secs_f64() / reps as f64);
            std::hint::black_box(&acc);
            let t = Instant::now();
            let mut acc2 = DMatrix::<f64>::zeros(p, p);
            for _ in 0..reps {
                let at = DMatrixView::from_slice_with_strides(a.as_slice(), p, m, m, 1);
                acc2.gemm(1.0, &at, &a, 1.0);
            }
            best[1] = best[1].min(t.elapsed().as_secs_f64() / reps as f64);
            std::hint::black_box(&acc2);
            let t = Instant::now();
            let mut acc3 = DMatrix::<f64>::zeros(p, p);
            for _ in 0..reps {
                let at = a.transpose();
                acc3.gemm(1.0, &at, &a, 1.0);
            }
            best[2] = best[2].min(t.elapsed().as_secs_f64() / reps as f64);
            assert!((&acc - &acc2).amax() < 1e-9 * acc.amax());
        }
        let flops = 2.0 * (m * p * p) as f64;
        println!("{m}x{p}: tr_mul {:.2} us ({:.2} GF/s), gemm view {:.2} us ({:.2} GF/s), gemm copy {:.2} us",
            best[0]*1e6, flops/best[0]/1e9, best[1]*1e6, flops/best[1]/1e9, best[2]*1e6);
    }
}
