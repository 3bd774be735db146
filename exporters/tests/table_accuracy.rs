//! How well the tabulated p(h) reproduces the exact lobe sum: `eval_from_table` vs `eval_lobes`,
//! per table resolution. Prints the error table (run with `--nocapture`) and asserts the default
//! resolution is within 1 % wherever the BRDF is not negligible (definitions below).
//!
//! Inputs: the fixture material (J = 49 anisotropic lobes, λ = 81.06, i.e. σ = π/40, the narrowest
//! lobes glint fits). Outputs: pass/fail and the table. Invariants: deterministic sampling.
//!
//! Where the error is largest: bilinear interpolation is second order inside the table, but the
//! hemi-octahedral map folds along the planes h.x = 0 and h.y = 0 (the table's diagonals), so
//! within about a texel of those the error is first order. The `max` columns are those places. (The
//! grid is corner-aligned, so the horizon itself is sampled and needs no clamping.)

mod common;

use common::*;
use glint_exporters::brdf::lobes_p;
use glint_exporters::{
    DEFAULT_TABLE_RESOLUTION, PhTable, eval_from_table, eval_lobes, hemi_oct_decode,
};

#[derive(Debug)]
struct Stats {
    /// max |p_table − p| / max p, over all h.
    abs_of_peak: f64,
    /// Relative error of p where p ≥ 10 % of its peak: max.
    core_max: f64,
    /// Relative error of p where p ≥ 1 % of its peak: max and 99.9th percentile.
    tail_max: f64,
    tail_p999: f64,
    /// Max relative error of f_r over random pairs (k1, k2 ≥ 0.1): with the fixture's ρd, and of
    /// the pure specular BRDF (ρd = 0) where it is ≥ 1 % of its peak.
    f_full: f64,
    f_spec: f64,
}

fn measure(resolution: u32) -> Stats {
    let mut desc = material("acc", 8);
    desc.table = PhTable::tabulate(resolution, |h| lobes_p(&desc, h));
    let r = resolution as usize;
    let mut pmax = 0f64;
    for y in 0..r {
        for x in 0..r {
            let h = hemi_oct_decode(x as f64 / (r - 1) as f64, y as f64 / (r - 1) as f64);
            pmax = pmax.max(lobes_p(&desc, h).iter().cloned().fold(0.0, f64::max));
        }
    }
    let mut rng = Rng(42);
    let (mut abs_of_peak, mut core_max) = (0f64, 0f64);
    let mut tail = Vec::new();
    for _ in 0..400_000 {
        let h = rng.hemisphere(0.0);
        let (e, t) = (lobes_p(&desc, h), desc.table.lookup(h));
        for k in 0..3 {
            let err = (t[k] - e[k]).abs();
            abs_of_peak = abs_of_peak.max(err / pmax);
            if e[k] >= 0.1 * pmax {
                core_max = core_max.max(err / e[k]);
            }
            if e[k] >= 0.01 * pmax {
                tail.push(err / e[k]);
            }
        }
    }
    tail.sort_by(|a, b| a.total_cmp(b));
    let tail_max = tail.last().copied().unwrap_or(0.0);
    let tail_p999 = tail[(tail.len() - 1) * 999 / 1000];
    // f_r over direction pairs: half uniform, half mirrored about a lobe centre (highlights).
    let mut spec = desc.clone();
    spec.rho_d = [0.0; 3];
    let mut pairs = Vec::new();
    for i in 0..100_000 {
        let wi = rng.hemisphere(0.1);
        let wo = if i % 2 == 0 {
            rng.hemisphere(0.1)
        } else {
            let c = desc.centres[i / 2 % desc.centres.len()];
            let d = 2.0 * (wi[0] * c[0] + wi[1] * c[1] + wi[2] * c[2]);
            let wo = [
                d * c[0] - wi[0] + 0.03 * (rng.uniform() - 0.5),
                d * c[1] - wi[1],
                d * c[2] - wi[2],
            ];
            let n = (wo[0] * wo[0] + wo[1] * wo[1] + wo[2] * wo[2]).sqrt();
            [wo[0] / n, wo[1] / n, wo[2] / n]
        };
        if wo[2] >= 0.1 {
            pairs.push((wi, wo));
        }
    }
    let smax = pairs
        .iter()
        .map(|(wi, wo)| {
            eval_lobes(&spec, *wi, *wo)
                .iter()
                .cloned()
                .fold(0.0, f64::max)
        })
        .fold(0.0, f64::max);
    let (mut f_full, mut f_spec) = (0f64, 0f64);
    for (wi, wo) in &pairs {
        let (a, b) = (
            eval_from_table(&desc, *wi, *wo),
            eval_lobes(&desc, *wi, *wo),
        );
        let (sa, sb) = (
            eval_from_table(&spec, *wi, *wo),
            eval_lobes(&spec, *wi, *wo),
        );
        for k in 0..3 {
            f_full = f_full.max((a[k] - b[k]).abs() / b[k]);
            if sb[k] >= 0.01 * smax {
                f_spec = f_spec.max((sa[k] - sb[k]).abs() / sb[k]);
            }
        }
    }
    Stats {
        abs_of_peak,
        core_max,
        tail_max,
        tail_p999,
        f_full,
        f_spec,
    }
}

#[test]
fn table_error_per_resolution() {
    eprintln!(
        "   R | |dp|/peak | p>=10%peak max | p>=1%peak max | p>=1%peak p99.9 | f_r (rho_d) max | f_r spec>=1% max"
    );
    let mut at_default = None;
    for r in [128u32, 256, 512, 1024] {
        let s = measure(r);
        eprintln!(
            "{r:>4} | {:>9.2e} | {:>14.2e} | {:>13.2e} | {:>15.2e} | {:>15.2e} | {:>16.2e}",
            s.abs_of_peak, s.core_max, s.tail_max, s.tail_p999, s.f_full, s.f_spec
        );
        if r == DEFAULT_TABLE_RESOLUTION {
            at_default = Some(s);
        }
    }
    let s = at_default.expect("the default resolution is one of those measured");
    // "Not negligible": the BRDF (or its specular part) at >= 1 % of its peak. Over random
    // direction pairs the specular BRDF and the full BRDF are within 1 %; over dense half-vectors
    // 99.9 % of p(h) >= 1 % of its peak is within 1 %, and the error is nowhere above 0.5 % of the
    // peak.
    assert!(s.f_spec < 0.01 && s.f_full < 0.01, "{s:?}");
    assert!(s.tail_p999 < 0.01 && s.abs_of_peak < 0.005, "{s:?}");
}
