//! Timing helpers the benches share (included by `#[path]`, as `tests/it/common.rs` is): the
//! median of repeated runs, in seconds.
#![allow(dead_code)] // each bench uses some of them

use std::time::Instant;

/// The median of `v` (the upper middle for an even count). `v` must not be empty.
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Median seconds of `n` (at least 1) timed runs of `f`, and the last result.
pub fn median_of<T>(n: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    match try_median_of(n, || Ok::<T, std::convert::Infallible>(f())) {
        Ok(timed) => timed,
        Err(never) => match never {},
    }
}

/// [`median_of`] for a fallible `f`: the first error ends the runs.
pub fn try_median_of<T, E>(n: usize, mut f: impl FnMut() -> Result<T, E>) -> Result<(f64, T), E> {
    let mut times = Vec::with_capacity(n.max(1));
    let mut timed = || {
        let t = Instant::now();
        let out = std::hint::black_box(f());
        times.push(t.elapsed().as_secs_f64());
        out
    };
    let mut last = timed()?;
    for _ in 1..n {
        last = timed()?;
    }
    Ok((median(times), last))
}

/// Median seconds of `n` (at least 1) timed runs of `f`.
pub fn time<T>(n: usize, f: impl FnMut() -> T) -> f64 {
    median_of(n, f).0
}

/// [`time`] for a fallible `f`: the first error ends the runs.
pub fn try_time<T, E>(n: usize, f: impl FnMut() -> Result<T, E>) -> Result<f64, E> {
    try_median_of(n, f).map(|(secs, _)| secs)
}
