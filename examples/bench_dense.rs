//! Dense Cholesky benchmark (not a test): for a range of n, faer's Cholesky factorization
//! of an n × n SPD matrix, and one solve with that factor by the plain loops of
//! `tsim::solve::small_solve` and by faer's kernel; prints per n the CPU time of each
//! (this thread's, from /proc/thread-self/schedstat, so that a loaded machine's waits do
//! not count). What `SMALL_SOLVE` (the size up to which the dense solver uses the loops)
//! is set from.
//!
//! Usage: bench_dense [SIZES...]   (default 8 16 32 52 64 96 128 200 300 400 600)

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::{factor, solve};
use faer::{Conj, Mat, Par};
use std::hint::black_box;
use tsim::solve::small_solve::{cholesky_in_place, cholesky_solve_in_place};

/// CPU time this thread has run [s] (Linux: the first field of schedstat, in ns).
fn thread_cpu() -> f64 {
    let text = std::fs::read_to_string("/proc/thread-self/schedstat").expect("Linux /proc/thread-self/schedstat");
    text.split_whitespace()
        .next()
        .and_then(|t| t.parse::<f64>().ok())
        .expect("a number")
        * 1e-9
}

/// A well-conditioned SPD matrix: B Bᵀ / n + I with B's entries from a fixed LCG in [-1, 1).
fn spd(n: usize) -> Mat<f64> {
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let b = Mat::from_fn(n, n, |_, _| {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    });
    Mat::from_fn(n, n, |i, j| {
        (0..n).map(|k| b[(i, k)] * b[(j, k)]).sum::<f64>() / n as f64 + if i == j { 1.0 } else { 0.0 }
    })
}

/// CPU seconds per call of `f`: batches of at least 0.1 s of CPU (schedstat is updated
/// at scheduler ticks, a few ms), best of 3.
fn per_call(mut f: impl FnMut()) -> f64 {
    let batch = |f: &mut dyn FnMut(), reps: usize| {
        let t = thread_cpu();
        for _ in 0..reps {
            f();
        }
        thread_cpu() - t
    };
    let mut reps = 1;
    while batch(&mut f, reps) < 0.1 {
        reps *= 2;
    }
    (0..3).map(|_| batch(&mut f, reps) / reps as f64).fold(f64::INFINITY, f64::min)
}

fn main() {
    let sizes: Vec<usize> = std::env::args().skip(1).map(|a| a.parse().expect("a size")).collect();
    let sizes = if sizes.is_empty() {
        vec![8, 16, 32, 52, 64, 96, 128, 200, 300, 400, 600]
    } else {
        sizes
    };
    println!(
        "{:>5} {:>13} {:>13} {:>13} {:>13}",
        "n", "faer factor", "loops factor", "loops solve", "faer solve"
    );
    for n in sizes {
        let a = spd(n);
        let rhs = vec![1.0; n];
        let req = StackReq::any_of(&[
            factor::cholesky_in_place_scratch::<f64>(n, Par::Seq, Default::default()),
            solve::solve_in_place_scratch::<f64>(n, 1, Par::Seq),
        ]);
        let mut mem = MemBuffer::new(req);
        let mut work = Mat::<f64>::zeros(n, n);
        let faer_factor = per_call(|| {
            work.copy_from(&a);
            factor::cholesky_in_place(
                work.as_mut(),
                Default::default(),
                Par::Seq,
                MemStack::new(&mut mem),
                Default::default(),
            )
            .expect("SPD");
        });
        let mut mine = Mat::<f64>::zeros(n, n);
        let loops_factor = per_call(|| {
            mine.copy_from(&a);
            cholesky_in_place(black_box(&mut mine)).expect("SPD");
        });
        let inv_diag: Vec<f64> = (0..n).map(|j| 1.0 / work[(j, j)]).collect();
        let mut x = rhs.clone();
        let loops_solve = per_call(|| {
            x.copy_from_slice(&rhs);
            cholesky_solve_in_place(&work, &inv_diag, black_box(&mut x));
        });
        let mut y = Mat::<f64>::zeros(n, 1);
        let faer_solve = per_call(|| {
            y.col_as_slice_mut(0).copy_from_slice(&rhs);
            solve::solve_in_place_with_conj(work.as_ref(), Conj::No, black_box(y.as_mut()), Par::Seq, MemStack::new(&mut mem));
        });
        let us = |t: f64| format!("{:.2} µs", t * 1e6);
        println!(
            "{n:>5} {:>13} {:>13} {:>13} {:>13}",
            us(faer_factor),
            us(loops_factor),
            us(loops_solve),
            us(faer_solve)
        );
    }
}
