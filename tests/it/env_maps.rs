//! Tests of `glint::env`: loading real EXR/HDR assets, sanitising, the equirectangular mapping,
//! solid angles, filtered lookup, rotation, statistics and refusal of bad input.
//!
//! References are independent of the code under test where possible: the `.hdr` and `.exr` copies
//! of one environment (different codecs), the 1k map box-filtered against the 512 map, the `exr`
//! crate read directly, glam's rotation matrices, and closed-form integrals over the sphere.

use std::f64::consts::PI;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use exr::prelude::{ReadChannels as _, ReadLayers as _};
use glam::{DMat3, DVec3};
use glint::env::{self, EnvError, EnvMap};

const ASSETS: &str = "/work/shared/assets/hdr";

fn asset(rel: &str) -> PathBuf {
    Path::new(ASSETS).join(rel)
}

/// A fresh, empty scratch directory for one test.
fn scratch(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("glint_env_maps_{}_{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// splitmix64: a tiny deterministic PRNG for the tests.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform on the unit sphere (Archimedes: z uniform in [-1, 1], azimuth uniform).
    fn direction(&mut self) -> DVec3 {
        let y = 2.0 * self.unit() - 1.0;
        let phi = 2.0 * PI * self.unit();
        let r = (1.0 - y * y).max(0.0).sqrt();
        DVec3::new(r * phi.cos(), y, r * phi.sin())
    }
}

fn rel_diff(a: f64, b: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs()).max(1e-30)
}

fn assert_sane(map: &EnvMap) {
    assert_eq!(map.texels().len(), map.width() * map.height());
    for (i, t) in map.texels().iter().enumerate() {
        for c in t {
            assert!(
                c.is_finite() && *c >= 0.0,
                "texel {i} of {} = {t:?}",
                map.source()
            );
        }
    }
    let peak = map
        .texels()
        .iter()
        .flat_map(|t| t.iter().copied())
        .fold(0.0f32, f32::max);
    assert_eq!(peak, map.stats().peak, "{}: peak", map.source());
}

// ---------------------------------------------------------------------------------------------
// Real assets

#[test]
fn small_studio_exr_half_float() {
    let map = env::load(&asset("small/studio_512.exr")).unwrap();
    let s = map.stats();
    println!("studio_512.exr: {}x{} {s:?}", map.width(), map.height());
    assert_eq!((map.width(), map.height()), (512, 256));
    assert!(map.is_two_to_one());
    assert_eq!(map.source(), "studio_512.exr");
    assert_eq!(s.clamped_texels, 0);
    assert_sane(&map);
    // The 1k original peaks at 118 (README); a 2x2 box filter can only lower it.
    assert!(s.peak > 1.0 && s.peak <= 118.5, "peak {}", s.peak);
    for m in s.mean_radiance {
        assert!(m > 0.01 && m < s.peak as f64, "mean {m}");
    }
}

/// The 512 map is the 2x2 box filter of the 1k map (README): check texel by texel, which pins the
/// row order, the column order and the channel order of both decoders (half vs f32 EXR).
#[test]
fn small_studio_is_box_filtered_1k() {
    let big = env::load(&asset("studio_1k.exr")).unwrap();
    let small = env::load(&asset("small/studio_512.exr")).unwrap();
    assert_eq!((big.width(), big.height()), (1024, 512));
    let mut worst = 0.0f64;
    for row in 0..small.height() {
        for col in 0..small.width() {
            let s = small.texel(col, row).unwrap();
            for (k, &sk) in s.iter().enumerate() {
                let mut sum = 0.0f64;
                for (dc, dr) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    sum += big.texel(2 * col + dc, 2 * row + dr).unwrap()[k] as f64;
                }
                let box_mean = sum / 4.0;
                // half float: 11-bit mantissa, relative step 2^-11 ≈ 4.9e-4.
                let err = (box_mean - sk as f64).abs() / (box_mean.abs() + 1e-3);
                worst = worst.max(err);
            }
        }
    }
    println!("studio 1k box-filtered vs 512: worst relative difference {worst:.2e}");
    assert!(worst < 2e-3, "worst relative difference {worst}");
    for k in 0..3 {
        let (a, b) = (big.stats().mean_radiance[k], small.stats().mean_radiance[k]);
        assert!(
            rel_diff(a, b) < 2e-3,
            "channel {k}: 1k mean {a} vs 512 mean {b}"
        );
    }
}

/// The same environment through two codecs and two decoders (OpenEXR half vs Radiance RGBE).
fn compare_exr_hdr(exr: &str, hdr: &str) {
    let a = env::load(&asset(exr)).unwrap();
    let b = env::load(&asset(hdr)).unwrap();
    println!("{exr}: {:?}\n{hdr}: {:?}", a.stats(), b.stats());
    assert_eq!((a.width(), a.height()), (512, 256));
    assert_eq!((b.width(), b.height()), (512, 256));
    assert_eq!(b.stats().clamped_texels, 0);
    assert_sane(&b);
    for k in 0..3 {
        let (ma, mb) = (a.stats().mean_radiance[k], b.stats().mean_radiance[k]);
        assert!(
            rel_diff(ma, mb) < 0.02,
            "channel {k}: exr mean {ma} vs hdr mean {mb}"
        );
    }
    assert!(rel_diff(a.stats().peak as f64, b.stats().peak as f64) < 0.02);
    // Texel by texel: RGBE keeps 8 mantissa bits of the largest channel, so every channel is
    // within ~1/256 of the texel's largest channel (plus the half-float rounding of the EXR).
    let mut worst = 0.0f64;
    for (ta, tb) in a.texels().iter().zip(b.texels()) {
        let scale = ta.iter().chain(tb.iter()).fold(0.0f32, |m, &c| m.max(c)) as f64 + 1e-6;
        for k in 0..3 {
            worst = worst.max((ta[k] as f64 - tb[k] as f64).abs() / scale);
        }
    }
    println!("{exr} vs {hdr}: worst texel difference / texel max = {worst:.2e}");
    assert!(worst < 1.2e-2, "worst {worst}");
}

#[test]
fn small_courtyard_exr_matches_hdr() {
    compare_exr_hdr("small/courtyard_512.exr", "small/courtyard_512.hdr");
}

#[test]
fn small_studio_exr_matches_hdr() {
    compare_exr_hdr("small/studio_512.exr", "small/studio_512.hdr");
}

#[test]
fn dwab_files_are_decoded_and_clamped() {
    for name in ["dwab/studio.exr", "dwab/forest.exr"] {
        let path = asset(name);
        let started = Instant::now();
        let map = env::load(&path).unwrap();
        let elapsed = started.elapsed();
        let s = map.stats();

        // Independent count: read the file with the exr crate directly.
        let raw = exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .first_valid_layer()
            .all_attributes()
            .from_file(&path)
            .unwrap();
        let layer = &raw.layer_data;
        let channel = |n: &str| {
            layer
                .channel_data
                .list
                .iter()
                .find(|c| c.name.eq(n))
                .unwrap()
                .sample_data
                .values_as_f32()
                .collect::<Vec<f32>>()
        };
        let (r, g, b) = (channel("R"), channel("G"), channel("B"));
        let bad = (0..r.len())
            .filter(|&i| {
                [r[i], g[i], b[i]]
                    .iter()
                    .any(|c| !c.is_finite() || *c < 0.0)
            })
            .count();
        let most_negative = r.iter().chain(&g).chain(&b).fold(0.0f32, |m, &c| m.min(c));
        println!(
            "{name}: {}x{}, clamped_texels = {} (independent count {bad}), most negative {most_negative}, \
             peak {}, mean {:?}, loaded in {elapsed:?}",
            map.width(),
            map.height(),
            s.clamped_texels,
            s.peak,
            s.mean_radiance
        );
        assert_eq!(
            (layer.size.width(), layer.size.height()),
            (map.width(), map.height())
        );
        assert!(s.clamped_texels > 0, "{name}: DWAB negatives expected");
        assert_eq!(s.clamped_texels, bad);
        assert!(
            most_negative >= -0.0041,
            "{name}: most negative {most_negative}"
        );
        assert_sane(&map);
        // Untouched texels are bit-identical to the direct decode.
        let w = map.width();
        for (i, t) in map.texels().iter().enumerate() {
            let src = [r[i], g[i], b[i]];
            for k in 0..3 {
                let expect = if src[k] >= 0.0 { src[k] } else { 0.0 };
                assert_eq!(
                    t[k],
                    expect,
                    "{name}: texel ({}, {}) channel {k}",
                    i % w,
                    i / w
                );
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Construction and statistics

#[test]
fn from_rgb_sanitises_and_counts_once_per_texel() {
    let texels = vec![
        [1.0, 2.0, 3.0],
        [f32::NAN, 1.0, 1.0],
        [f32::INFINITY, f32::NEG_INFINITY, -1.0], // three bad channels, one texel
        [0.5, -1.0, 0.25],
        [-0.0, 0.0, 4.0],
        [0.0, 0.0, f32::NAN],
        [7.0, 0.0, 0.0],
        [0.0, 0.0, 0.0],
    ];
    let map = EnvMap::from_rgb(4, 2, texels, "unit").unwrap();
    assert_eq!(map.source(), "unit");
    assert_eq!(map.stats().clamped_texels, 4);
    assert_eq!(map.stats().peak, 7.0);
    let expect = [
        [1.0, 2.0, 3.0],
        [0.0, 1.0, 1.0],
        [0.0, 0.0, 0.0],
        [0.5, 0.0, 0.25],
        [0.0, 0.0, 4.0],
        [0.0, 0.0, 0.0],
        [7.0, 0.0, 0.0],
        [0.0, 0.0, 0.0],
    ];
    assert_eq!(map.texels(), &expect);
    assert!(map.texels().iter().flatten().all(|c| c.is_sign_positive()));
    assert!(!map.is_two_to_one() || map.width() == 2 * map.height());
    assert!(map.is_two_to_one());

    assert!(matches!(
        EnvMap::from_rgb(0, 2, vec![], "x"),
        Err(EnvError::Empty { .. })
    ));
    assert!(matches!(
        EnvMap::from_rgb(4, 0, vec![], "x"),
        Err(EnvError::Empty { .. })
    ));
    assert!(matches!(
        EnvMap::from_rgb(4, 2, vec![[0.0; 3]; 7], "x"),
        Err(EnvError::SizeMismatch { len: 7, .. })
    ));
    let err = EnvMap::from_rgb(4, 2, vec![[0.0; 3]; 9], "x")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains('x') && err.contains("4x2") && !err.contains('\n'),
        "{err}"
    );
    assert!(
        !EnvMap::from_rgb(3, 2, vec![[0.0; 3]; 6], "x")
            .unwrap()
            .is_two_to_one()
    );
}

#[test]
fn solid_angles_sum_to_4pi() {
    for (w, h) in [(512, 256), (1024, 512), (7, 3), (1, 1), (4096, 2048)] {
        let map = EnvMap::uniform(w, h, [1.0; 3]).unwrap();
        let total: f64 = (0..h).map(|r| map.texel_solid_angle(r) * w as f64).sum();
        assert!((total - 4.0 * PI).abs() < 1e-12, "{w}x{h}: {total}");
        // Independent: each row's band is 2π(cos θ0 - cos θ1) / W.
        for r in [0, h / 2, h - 1] {
            let (t0, t1) = (PI * r as f64 / h as f64, PI * (r + 1) as f64 / h as f64);
            let expect = 2.0 * PI / w as f64 * (t0.cos() - t1.cos());
            assert!(
                (map.texel_solid_angle(r) - expect).abs() < 1e-15,
                "{w}x{h} row {r}"
            );
        }
        let u = map.stats().mean_radiance;
        assert!(
            u.iter().all(|m| (m - 1.0).abs() < 1e-12),
            "uniform mean {u:?}"
        );
    }
}

#[test]
fn mean_radiance_is_solid_angle_weighted() {
    let (w, h) = (256, 128);
    // 1 + d.y integrates to 4π over the sphere: mean 1.
    let map = EnvMap::from_fn(w, h, |d| [(1.0 + d.y) as f32; 3]).unwrap();
    for m in map.stats().mean_radiance {
        assert!((m - 1.0).abs() < 1e-3, "mean of 1 + y = {m}");
    }
    // y² has sphere mean 1/3; an unweighted texel mean would give ~1/2 (rows are uniform in θ).
    let map = EnvMap::from_fn(w, h, |d| [(d.y * d.y) as f32, 0.0, 1.0]).unwrap();
    let m = map.stats().mean_radiance;
    let unweighted =
        map.texels().iter().map(|t| t[0] as f64).sum::<f64>() / map.texels().len() as f64;
    println!("mean of y^2: weighted {} vs unweighted {unweighted}", m[0]);
    assert!(
        (m[0] - 1.0 / 3.0).abs() < 1e-3,
        "weighted mean of y^2 = {}",
        m[0]
    );
    assert!((unweighted - 0.5).abs() < 1e-2, "unweighted = {unweighted}");
    assert!((m[2] - 1.0).abs() < 1e-12);
    // Only the top row lit: mean = (1 - cos(π/H)) / 2 exactly.
    let mut texels = vec![[0.0f32; 3]; w * h];
    texels[..w].fill([1.0; 3]);
    let map = EnvMap::from_rgb(w, h, texels, "cap").unwrap();
    let expect = (1.0 - (PI / h as f64).cos()) / 2.0;
    let got = map.stats().mean_radiance[0];
    assert!(rel_diff(got, expect) < 1e-9, "{got} vs {expect}");
}

// ---------------------------------------------------------------------------------------------
// Mapping

#[test]
fn direction_uv_round_trip_and_axes() {
    let mut rng = Rng(0x5EED);
    for _ in 0..1000 {
        let d = rng.direction();
        let (u, v) = env::direction_to_uv(d);
        assert!(
            (0.0..1.0).contains(&u) && (0.0..=1.0).contains(&v),
            "{u} {v}"
        );
        let back = env::uv_to_direction(u, v);
        assert!((back - d).length() < 1e-12, "{d} -> ({u}, {v}) -> {back}");
        let (u2, v2) = env::direction_to_uv(back);
        let du = (u2 - u).abs().min(1.0 - (u2 - u).abs()); // u wraps
        assert!(du < 1e-12 && (v2 - v).abs() < 1e-12);
    }
    // The documented formulas, checked at the axes.
    let close = |a: DVec3, b: DVec3| (a - b).length() < 1e-15;
    assert!(close(env::uv_to_direction(0.5, 0.5), DVec3::NEG_Z));
    assert!(close(env::uv_to_direction(0.75, 0.5), DVec3::X));
    assert!(close(env::uv_to_direction(0.25, 0.5), DVec3::NEG_X));
    assert!(close(env::uv_to_direction(0.0, 0.5), DVec3::Z));
    assert!(close(env::uv_to_direction(0.3, 0.0), DVec3::Y));
    assert!(close(env::uv_to_direction(0.3, 1.0), DVec3::NEG_Y));
    let uv = |d: DVec3| env::direction_to_uv(d);
    assert_eq!(uv(DVec3::NEG_Z), (0.5, 0.5));
    assert_eq!(uv(DVec3::X), (0.75, 0.5));
    assert_eq!(uv(DVec3::NEG_X), (0.25, 0.5));
    assert_eq!(uv(DVec3::Z).0, 0.0);
    assert_eq!(uv(DVec3::Y).1, 0.0);
    assert_eq!(uv(DVec3::NEG_Y).1, 1.0);
    // Non-unit input is normalised.
    let (u, v) = uv(DVec3::new(0.0, 3.0, -3.0));
    assert!((u - 0.5).abs() < 1e-15 && (v - 0.25).abs() < 1e-15);

    // Texel centres: row 0 is the top.
    let map = EnvMap::uniform(8, 4, [1.0; 3]).unwrap();
    let top = map.texel_direction(0, 0);
    assert!(top.y > 0.9 && (top.length() - 1.0).abs() < 1e-15);
    let (u, v) = uv(map.texel_direction(5, 2));
    assert!((u - 5.5 / 8.0).abs() < 1e-12 && (v - 2.5 / 4.0).abs() < 1e-12);
}

/// A smooth, positive test function of direction.
fn smooth(d: DVec3) -> f64 {
    4.0 + d.x + 2.0 * d.z
}

#[test]
fn lookup_is_bilinear_over_texel_centres() {
    let (w, h) = (256, 128);
    let map = EnvMap::from_fn(w, h, |d| [smooth(d) as f32, 1.0, (2.0 * smooth(d)) as f32]).unwrap();
    // smooth() = 4 + √5 sinθ sin(φ - α): second derivatives in φ and θ are bounded by √5, so the
    // bilinear error is at most √5 (Δφ² + Δθ²) / 8.
    let (dphi, dtheta) = (2.0 * PI / w as f64, PI / h as f64);
    let tol = 5f64.sqrt() * (dphi * dphi + dtheta * dtheta) / 8.0 * 1.05 + 1e-6;
    // Half a texel off would cost about √5 · Δ/2 ≈ 0.027, far above tol ≈ 3.5e-4.
    let mut rng = Rng(42);
    let mut worst = 0.0f64;
    let mut n = 0;
    while n < 2000 {
        let d = rng.direction();
        let (_, v) = env::direction_to_uv(d);
        if v < 0.5 / h as f64 || v > 1.0 - 0.5 / h as f64 {
            continue; // between the pole and the first row of centres: clamped, checked below
        }
        let got = map.lookup(d, 0.0);
        worst = worst.max((got[0] - smooth(d)).abs());
        assert!((got[1] - 1.0).abs() < 1e-12);
        assert!((got[2] - 2.0 * got[0]).abs() < 1e-5);
        n += 1;
    }
    println!("bilinear lookup: worst error {worst:.2e}, bound {tol:.2e}");
    assert!(worst <= tol, "worst {worst} > {tol}");
    // Exactly at texel centres lookup returns the texel.
    for (col, row) in [(0, 0), (17, 5), (255, 127), (128, 64)] {
        let got = map.lookup(map.texel_direction(col, row), 0.0)[0];
        let texel = map.texel(col, row).unwrap()[0] as f64;
        assert!(
            (got - texel).abs() < 1e-5,
            "({col}, {row}): {got} vs {texel}"
        );
    }
    // Horizontal wrap: on the seam (+Z) the value is the mean of the first and last columns.
    let d = env::uv_to_direction(0.0, 0.5 - 0.5 / h as f64 + 1e-12);
    let got = map.lookup(d, 0.0)[0];
    let row = h / 2 - 1;
    let expect = 0.5 * (map.texel(0, row).unwrap()[0] + map.texel(w - 1, row).unwrap()[0]) as f64;
    assert!((got - expect).abs() < 1e-5, "seam {got} vs {expect}");
    // Vertical clamp: at the poles the value is the mean of the first (last) row's two nearest.
    assert!((map.lookup(DVec3::Y, 0.0)[0] - smooth(DVec3::Y)).abs() < 5f64.sqrt() * dtheta);
    assert!((map.lookup(DVec3::NEG_Y, 0.0)[0] - smooth(DVec3::NEG_Y)).abs() < 5f64.sqrt() * dtheta);
    // With a latitude-only function, between a pole and the nearest row of centres the value is
    // exactly that row's (clamped, not wrapped to the other pole).
    let lat = EnvMap::from_fn(w, h, |d| [(4.0 + 3.0 * d.y) as f32; 3]).unwrap();
    let first_row = 4.0 + 3.0 * (0.5 * dtheta).cos();
    let last_row = 4.0 - 3.0 * (0.5 * dtheta).cos();
    for (d, expect) in [
        (DVec3::Y, first_row),
        (DVec3::NEG_Y, last_row),
        (env::uv_to_direction(0.3, 0.2 / h as f64), first_row),
        (env::uv_to_direction(0.7, 1.0 - 0.2 / h as f64), last_row),
    ] {
        let got = lat.lookup(d, 0.0)[0];
        assert!((got - expect).abs() < 1e-5, "{d}: {got} vs {expect}");
    }
}

#[test]
fn lookup_rotation_about_y() {
    let (w, h) = (256, 128);
    let map = EnvMap::from_fn(w, h, |d| [smooth(d) as f32; 3]).unwrap();
    let (dphi, dtheta) = (2.0 * PI / w as f64, PI / h as f64);
    let tol = 5f64.sqrt() * (dphi * dphi + dtheta * dtheta) / 8.0 * 1.05 + 1e-6;
    let mut rng = Rng(7);
    for i in 0..500 {
        let theta = (rng.unit() - 0.5) * 4.0 * PI;
        let d = rng.direction();
        let r = DMat3::from_rotation_y(-theta) * d; // glam: right-handed rotation about +Y
        let a = map.lookup(d, theta);
        let b = map.lookup(r, 0.0);
        for k in 0..3 {
            assert!((a[k] - b[k]).abs() < 1e-9, "case {i}: {a:?} vs {b:?}");
        }
        let (_, v) = env::direction_to_uv(r);
        if v > 0.5 / h as f64 && v < 1.0 - 0.5 / h as f64 {
            assert!((a[0] - smooth(r)).abs() <= tol, "case {i}");
        }
    }
    // Right-hand rule: rotating the environment by +90° carries what was at -Z to -X.
    let at_minus_z = map.lookup(DVec3::NEG_Z, 0.0)[0];
    let rotated = map.lookup(DVec3::NEG_X, PI / 2.0)[0];
    assert!(
        (at_minus_z - rotated).abs() < 1e-4,
        "{at_minus_z} vs {rotated}"
    );
    assert!((map.lookup(DVec3::NEG_Z, PI / 2.0)[0] - map.lookup(DVec3::X, 0.0)[0]).abs() < 1e-4);
    assert!((at_minus_z - smooth(DVec3::NEG_Z)).abs() < tol);
    assert!((map.lookup(DVec3::NEG_X, 0.0)[0] - at_minus_z).abs() > 0.5);
}

// ---------------------------------------------------------------------------------------------
// Bad input

fn write_exr_single_channel(path: &Path, name: &str, w: usize, h: usize) {
    use exr::prelude::*;
    let samples: Vec<f32> = (0..w * h).map(|i| i as f32).collect();
    let channel = AnyChannel::new(name, FlatSamples::F32(samples));
    let layer = Layer::new(
        (w, h),
        LayerAttributes::named("main"),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(vec![channel])),
    );
    Image::from_layer(layer).write().to_file(path).unwrap();
}

#[test]
fn missing_file_is_io_error() {
    let err = env::load(Path::new("/nonexistent/glint/nowhere.exr")).unwrap_err();
    assert!(matches!(err, EnvError::Io { .. }), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains("nowhere.exr") && !msg.contains('\n'), "{msg}");
    let err = env::load(Path::new("/nonexistent/glint/nowhere.HDR")).unwrap_err();
    assert!(matches!(err, EnvError::Io { .. }), "{err:?}");
}

#[test]
fn unsupported_extension() {
    let dir = scratch("ext");
    let png = dir.join("sky.png");
    std::fs::write(&png, b"\x89PNG\r\n\x1a\n").unwrap();
    let err = env::load(&png).unwrap_err();
    assert!(
        matches!(&err, EnvError::UnsupportedExtension { ext, .. } if ext == "png"),
        "{err:?}"
    );
    let msg = err.to_string();
    assert!(
        msg.contains("sky.png") && msg.contains("png") && !msg.contains('\n'),
        "{msg}"
    );
    let err = env::load(&dir.join("noext")).unwrap_err();
    assert!(
        matches!(err, EnvError::UnsupportedExtension { .. }),
        "{err:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn extension_is_case_insensitive() {
    let dir = scratch("case");
    let upper = dir.join("STUDIO.EXR");
    std::fs::copy(asset("small/studio_512.exr"), &upper).unwrap();
    let map = env::load(&upper).unwrap();
    assert_eq!(
        (map.width(), map.height(), map.source()),
        (512, 256, "STUDIO.EXR")
    );
    let upper = dir.join("Court.Hdr");
    std::fs::copy(asset("small/courtyard_512.hdr"), &upper).unwrap();
    assert_eq!(env::load(&upper).unwrap().width(), 512);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn truncated_files_are_errors_not_panics() {
    let dir = scratch("truncated");
    for (src, name) in [
        ("small/studio_512.exr", "cut.exr"),
        ("dwab/forest.exr", "cut_dwab.exr"),
        ("small/courtyard_512.hdr", "cut.hdr"),
    ] {
        let bytes = std::fs::read(asset(src)).unwrap();
        for len in [0, 8, 1000, bytes.len() / 2, bytes.len() - 1] {
            let path = dir.join(name);
            std::fs::write(&path, &bytes[..len]).unwrap();
            let err = env::load(&path).unwrap_err();
            let msg = err.to_string();
            println!("{src} cut to {len} bytes: {msg}");
            assert!(msg.contains(name) && !msg.contains('\n'), "{msg}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn huge_hdr_header_is_refused_before_allocating() {
    let dir = scratch("huge_hdr");
    for (dims, w, h) in [
        ("-Y 100000 +X 100000", 100_000, 100_000),
        ("-Y 8192 +X 16384", 16384, 8192),
    ] {
        let path = dir.join("huge.hdr");
        let header = format!("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n{dims}\n");
        std::fs::write(&path, header).unwrap();
        let started = Instant::now();
        let err = env::load(&path).unwrap_err();
        let elapsed = started.elapsed();
        assert!(
            matches!(err, EnvError::TooLarge { width, height, .. } if width == w && height == h),
            "{err:?}"
        );
        assert!(elapsed < Duration::from_millis(200), "took {elapsed:?}");
        let msg = err.to_string();
        assert!(
            msg.contains("huge.hdr") && msg.contains(&format!("{w}x{h}")),
            "{msg}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn huge_exr_header_is_refused_before_allocating() {
    // Write a valid 4x4 RGB EXR, then patch its dataWindow to declare 100000 x 100000.
    use exr::prelude::*;
    let dir = scratch("huge_exr");
    let path = dir.join("huge.exr");
    let px = SpecificChannels::rgb(|_pos: Vec2<usize>| (0.5f32, 0.5f32, 0.5f32));
    Image::from_channels((4, 4), px)
        .write()
        .to_file(&path)
        .unwrap();
    let mut bytes = std::fs::read(&path).unwrap();
    let key = b"dataWindow\0box2i\0";
    let at = bytes.windows(key.len()).position(|w| w == key).unwrap() + key.len();
    assert_eq!(&bytes[at..at + 4], &16i32.to_le_bytes()); // attribute size
    let bx = at + 4; // xMin, yMin, xMax, yMax
    bytes[bx + 8..bx + 12].copy_from_slice(&99_999i32.to_le_bytes());
    bytes[bx + 12..bx + 16].copy_from_slice(&99_999i32.to_le_bytes());
    std::fs::write(&path, &bytes).unwrap();
    let started = Instant::now();
    let err = env::load(&path).unwrap_err();
    assert!(
        started.elapsed() < Duration::from_millis(200),
        "took {:?}",
        started.elapsed()
    );
    assert!(
        matches!(
            err,
            EnvError::TooLarge {
                width: 100_000,
                height: 100_000,
                ..
            }
        ),
        "{err:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn exr_without_rgb_channels() {
    let dir = scratch("no_rgb");
    let path = dir.join("depth.exr");
    write_exr_single_channel(&path, "Z", 8, 4);
    let err = env::load(&path).unwrap_err();
    match &err {
        EnvError::NoRgbChannels { channels, .. } => assert_eq!(channels, &["Z".to_string()]),
        other => panic!("expected NoRgbChannels, got {other:?}"),
    }
    let msg = err.to_string();
    assert!(
        msg.contains("depth.exr") && msg.contains('Z') && !msg.contains('\n'),
        "{msg}"
    );

    // A luminance-only image is accepted as grey.
    let path = dir.join("grey.exr");
    write_exr_single_channel(&path, "Y", 8, 4);
    let map = env::load(&path).unwrap();
    assert_eq!((map.width(), map.height()), (8, 4));
    for row in 0..4 {
        for col in 0..8 {
            let y = (row * 8 + col) as f32;
            assert_eq!(map.texel(col, row).unwrap(), [y, y, y]);
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Layout of a hand-written EXR: texel (col, row) = (col, row, 7) with row 0 at the top; negative
/// and non-finite values written to the file are clamped on load.
#[test]
fn exr_layout_and_clamping() {
    use exr::prelude::*;
    let dir = scratch("layout");
    let path = dir.join("layout.exr");
    let px = SpecificChannels::rgb(|pos: Vec2<usize>| {
        let (x, y) = (pos.x() as f32, pos.y() as f32);
        if (pos.x(), pos.y()) == (3, 1) {
            (-2.0f32, f32::NAN, 1.0f32)
        } else {
            (x, y, 7.0f32)
        }
    });
    Image::from_channels((6, 4), px)
        .write()
        .to_file(&path)
        .unwrap();
    let map = env::load(&path).unwrap();
    assert_eq!((map.width(), map.height()), (6, 4));
    assert!(!map.is_two_to_one());
    assert_eq!(map.stats().clamped_texels, 1);
    for row in 0..4 {
        for col in 0..6 {
            let expect = if (col, row) == (3, 1) {
                [0.0, 0.0, 1.0]
            } else {
                [col as f32, row as f32, 7.0]
            };
            assert_eq!(map.texel(col, row).unwrap(), expect, "({col}, {row})");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
