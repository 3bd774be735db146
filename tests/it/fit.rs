//! The fit on real problems (bunny and teapot under courtyard): recovery of known coefficients, the
//! objective against Clarabel with constraints and KKT checked, and every hard case of method.md §9
//! that belongs to the fit.

use crate::common;

use glint::bake::{BakeSettings, Baker};
use glint::env::EnvMap;
use glint::fit::problem::{ChannelSystem, ViewData, normal_equations};
use glint::fit::qp::{QpProblem, kkt_residuals};
use glint::fit::run::{Baked, FitSettings, fit};
use glint::fit::strokes::{self, ViewStrokes};
use glint::light::LightSums;
use glint::scene::Scene;
use glint::sphere::{LobeLayout, LobeSet, srbf};
use glint::transfer::TransferContext;

fn setup(mesh: &str, env: &EnvMap) -> (Scene, glint::bake::Bake, usize) {
    let scene = glint::scene::import(&common::assets().join(format!("glb/{mesh}.glb"))).unwrap();
    let baker = Baker::new(
        &scene,
        env,
        BakeSettings {
            resolution: Some(32),
            ..BakeSettings::default()
        },
    )
    .unwrap();
    let bake = baker.bake_all(None, &|_| {});
    (scene, bake, 32)
}

fn courtyard() -> EnvMap {
    glint::env::load(&common::assets().join("hdr/small/courtyard_512.exr")).unwrap()
}

fn strokes(json: &str) -> Vec<ViewStrokes> {
    strokes::parse(json).unwrap()
}

const BRIGHT: &str = r#"{"view": "default", "image_size": [640, 480], "strokes": [
    {"points": [[300, 180], [340, 200], [360, 240]], "mode": "paint", "color": [8, 7, 6], "radius": 18, "kappa": 0.05},
    {"points": [[250, 300], [260, 320]], "mode": "scale", "scale": 0.2, "radius": 25, "kappa": 0.02}]}"#;

const MODERATE: &str = r#"{"view": "default", "image_size": [640, 480], "strokes": [
    {"points": [[300, 180], [340, 200]], "mode": "paint", "color": [0.6, 0.55, 0.5], "radius": 20, "kappa": 0.05}]}"#;

#[test]
fn known_coefficients_are_recovered_to_1e_4() {
    let env = courtyard();
    let (scene, bake, n) = setup("bunny", &env);
    let set = glint::sphere::DirectionSet::cube(n).unwrap();
    let tree = glint::sphere::LightTree::build(&set);
    let light = LightSums::new(&env, &set, &tree, 0.0);
    let lobes = LobeSet::new(
        LobeLayout::Isotropic { count: 24 },
        srbf::lambda_from_sigma(srbf::PAPER_SIGMA).unwrap(),
    )
    .unwrap();
    let transfer = TransferContext::new(&scene.mesh, &bake.cuts, &tree, &lobes, None, None)
        .compute(&light, &scene.cameras[0], 160, 120, 0.04);
    let energy = glint::brdf::EnergyTable::with_defaults(&lobes);
    let rho_d = [0.4, 0.3, 0.2];
    // A plausible specular lobe: a few rings, well inside the energy bound.
    let mut truth = vec![0.0; lobes.len()];
    truth[0] = 0.8;
    truth[3] = 0.5;
    truth[9] = 0.3;
    assert!(
        energy.albedo(&truth, 0.04).iter().all(|&a| a <= 0.6),
        "truth must be feasible"
    );
    let image = transfer.render(rho_d, [&truth, &truth, &truth]);
    let weight = vec![1.0; image.len()];
    let data = [ViewData {
        transfer: &transfer,
        target: &image,
        weight: &weight,
    }];
    for c in 0..3 {
        let system = ChannelSystem::new(
            normal_equations(&data, c, rho_d[c]),
            Some((&energy, 0.04)),
            rho_d[c],
        )
        .unwrap();
        let fitted = system.solve(None).unwrap();
        let mut coeffs = [
            vec![0.0; lobes.len()],
            vec![0.0; lobes.len()],
            vec![0.0; lobes.len()],
        ];
        coeffs[c] = fitted.coefficients.clone();
        let back = transfer.render(rho_d, [&coeffs[0], &coeffs[1], &coeffs[2]]);
        let num: f64 = back
            .iter()
            .zip(&image)
            .map(|(a, b)| (a[c] - b[c]).powi(2))
            .sum();
        let den: f64 = image.iter().map(|b| b[c] * b[c]).sum();
        let rel = (num / den).sqrt();
        println!(
            "recovery channel {c}: relative image residual {rel:.2e}, {} iterations",
            fitted.iterations
        );
        assert!(rel <= 1e-4, "channel {c}: {rel}");
    }
}

#[test]
fn real_problems_match_clarabel_and_satisfy_kkt() {
    let env = courtyard();
    for mesh in ["bunny", "teapot"] {
        let (scene, bake, n) = setup(mesh, &env);
        for (label, json) in [("bright", BRIGHT), ("moderate", MODERATE)] {
            let out = fit(
                &Baked {
                    scene: &scene,
                    env: &env,
                    cuts: &bake.cuts,
                    resolution: n,
                    tangents: None,
                    anisotropic: false,
                },
                &strokes(json),
                &FitSettings::default(),
            )
            .unwrap();
            let energy = out.energy.as_ref().unwrap();
            let j = out.material.centres.len();
            let g = energy.matrix(0.04);
            for c in 0..3 {
                let data: Vec<ViewData> = out
                    .views
                    .iter()
                    .map(|v| ViewData {
                        transfer: &v.transfer,
                        target: &v.target,
                        weight: &v.weight,
                    })
                    .collect();
                let eq = normal_equations(&data, c, 0.5);
                let q: Vec<f64> = eq.r.iter().map(|x| -x).collect();
                let u = vec![0.5; energy.rows()];
                let ours = &out.material.coefficients[c];
                let reference = common::clarabel_qp(&eq.h, &q, &g, &u, j, energy.rows());
                let (fo, fr) = (
                    common::qp_objective(&eq.h, &q, ours, j),
                    common::qp_objective(&eq.h, &q, &reference, j),
                );
                let rel = (fo - fr).abs() / fr.abs().max(1e-300);
                assert!(
                    rel <= 1e-6,
                    "{mesh} {label} c{c}: objective {fo} vs clarabel {fr}"
                );
                assert!(ours.iter().all(|&x| x >= 0.0));
                for l in 0..energy.rows() {
                    let row: f64 = (0..j).map(|k| g[l * j + k] * ours[k]).sum();
                    assert!(row <= 0.5 + 1e-9, "{mesh} {label}: energy row {l} = {row}");
                }
                // KKT at our solution, from the solver's own report of multipliers.
                let problem = QpProblem {
                    h: &eq.h,
                    q: &q,
                    g: &g,
                    u: &u,
                    n: j,
                    m: energy.rows(),
                };
                let system = ChannelSystem::new(eq.clone(), Some((energy, 0.04)), 0.5).unwrap();
                let _ = system;
                let sol = glint::fit::qp::solve(&problem).unwrap();
                let kkt = kkt_residuals(&problem, &sol);
                assert!(
                    kkt.stationarity_relative <= 1e-8
                        && kkt.primal_infeasibility <= 1e-9
                        && kkt.dual_infeasibility <= 0.0,
                    "{mesh} {label}: {kkt:?}"
                );
                println!(
                    "{mesh} {label} c{c}: objective {fo:.6e} (clarabel {fr:.6e}, rel {rel:.1e}); active rows {}",
                    out.material.fit.active_energy_rows[c]
                );
            }
            if label == "bright" {
                // Targets brighter than energy allows: the energy rows bind and the residual is
                // reported.
                assert!(
                    out.material.fit.active_energy_rows.iter().all(|&r| r > 0),
                    "{mesh}: {:?}",
                    out.material.fit
                );
                assert!(
                    out.material
                        .fit
                        .residual_rms
                        .iter()
                        .all(|&r| r > 0.0 && r.is_finite())
                );
            }
        }
    }
}

#[test]
fn empty_and_off_object_strokes_are_handled_and_reported() {
    let env = courtyard();
    let (scene, bake, n) = setup("teapot", &env);
    let empty = strokes(r#"{"view": "default", "image_size": [640, 480], "strokes": []}"#);
    let out = fit(
        &Baked {
            scene: &scene,
            env: &env,
            cuts: &bake.cuts,
            resolution: n,
            tangents: None,
            anisotropic: false,
        },
        &empty,
        &FitSettings::default(),
    )
    .unwrap();
    assert!(
        out.material
            .coefficients
            .iter()
            .flatten()
            .all(|&c| c == 0.0)
    );
    assert!(
        out.material
            .fit
            .notes
            .iter()
            .any(|s| s.contains("no stroke")),
        "{:?}",
        out.material.fit.notes
    );
    let off = strokes(
        r#"{"view": "default", "image_size": [640, 480], "strokes": [
        {"points": [[2, 2], [10, 4]], "mode": "paint", "color": [5, 5, 5], "radius": 3, "kappa": 0.1}]}"#,
    );
    let out = fit(
        &Baked {
            scene: &scene,
            env: &env,
            cuts: &bake.cuts,
            resolution: n,
            tangents: None,
            anisotropic: false,
        },
        &off,
        &FitSettings::default(),
    )
    .unwrap();
    assert_eq!(out.material.fit.strokes_off_object, 1);
    assert!(out.material.fit.notes.iter().any(|s| s.contains("ignored")));
    // A stroke on the object plus one off it: the good one is fitted, the other counted.
    let mut mixed = strokes(BRIGHT);
    mixed[0].strokes.push(off[0].strokes[0].clone());
    let out = fit(
        &Baked {
            scene: &scene,
            env: &env,
            cuts: &bake.cuts,
            resolution: n,
            tangents: None,
            anisotropic: false,
        },
        &mixed,
        &FitSettings::default(),
    )
    .unwrap();
    assert_eq!(out.material.fit.strokes_off_object, 1);
    assert!(out.material.coefficients.iter().flatten().any(|&c| c > 0.0));
    // An unknown camera is a clear error.
    let bad = strokes(r#"{"view": "nope", "image_size": [640, 480], "strokes": []}"#);
    let err = fit(
        &Baked {
            scene: &scene,
            env: &env,
            cuts: &bake.cuts,
            resolution: n,
            tangents: None,
            anisotropic: false,
        },
        &bad,
        &FitSettings::default(),
    )
    .err()
    .unwrap()
    .to_string();
    assert!(err.contains("nope") && err.contains("default"), "{err}");
}

#[test]
fn hard_environments_and_lobe_widths_converge_deterministically() {
    let uniform = EnvMap::uniform(256, 128, [1.0; 3]).unwrap();
    let sun = EnvMap::from_fn(512, 256, |d| {
        let s = glam::DVec3::new(0.3, 0.8, 0.5).normalize();
        if d.dot(s) > 0.9995 {
            [1e5; 3]
        } else {
            [1e-3; 3]
        }
    })
    .unwrap();
    for (label, env, sigma) in [
        (
            "constant environment (T nearly rank-deficient)",
            &uniform,
            srbf::PAPER_SIGMA,
        ),
        ("sun of 1e5 in a 1e-3 sky", &sun, srbf::PAPER_SIGMA),
        ("λ = 1", &uniform, srbf::sigma_from_lambda(1.0).unwrap()),
        ("λ = 5000", &sun, srbf::sigma_from_lambda(5000.0).unwrap()),
    ] {
        let (scene, bake, n) = setup("teapot", env);
        let settings = FitSettings {
            sigma,
            ..FitSettings::default()
        };
        let a = fit(
            &Baked {
                scene: &scene,
                env,
                cuts: &bake.cuts,
                resolution: n,
                tangents: None,
                anisotropic: false,
            },
            &strokes(BRIGHT),
            &settings,
        )
        .unwrap();
        let b = fit(
            &Baked {
                scene: &scene,
                env,
                cuts: &bake.cuts,
                resolution: n,
                tangents: None,
                anisotropic: false,
            },
            &strokes(BRIGHT),
            &settings,
        )
        .unwrap();
        assert_eq!(
            a.material.coefficients, b.material.coefficients,
            "{label}: not deterministic"
        );
        let energy = a.energy.as_ref().unwrap();
        for c in 0..3 {
            let coeffs = &a.material.coefficients[c];
            assert!(coeffs.iter().all(|x| x.is_finite() && *x >= 0.0), "{label}");
            assert!(
                energy.albedo(coeffs, 0.04).iter().all(|&x| x <= 0.5 + 1e-9),
                "{label}: energy bound broken"
            );
        }
        println!(
            "{label}: residual {:?}, iterations {:?}",
            a.material.fit.residual_rms, a.material.fit.iterations
        );
    }
}

#[test]
fn without_the_energy_limit_only_non_negativity_holds() {
    let env = courtyard();
    let (scene, bake, n) = setup("teapot", &env);
    let settings = FitSettings {
        energy_limit: false,
        ..FitSettings::default()
    };
    let free = fit(
        &Baked {
            scene: &scene,
            env: &env,
            cuts: &bake.cuts,
            resolution: n,
            tangents: None,
            anisotropic: false,
        },
        &strokes(BRIGHT),
        &settings,
    )
    .unwrap();
    let bound = fit(
        &Baked {
            scene: &scene,
            env: &env,
            cuts: &bake.cuts,
            resolution: n,
            tangents: None,
            anisotropic: false,
        },
        &strokes(BRIGHT),
        &FitSettings::default(),
    )
    .unwrap();
    assert!(
        free.material
            .coefficients
            .iter()
            .flatten()
            .all(|&c| c >= 0.0)
    );
    // The unconstrained fit matches the bright paint better than the physical one can.
    for c in 0..3 {
        assert!(
            free.material.fit.residual_rms[c] < bound.material.fit.residual_rms[c],
            "channel {c}"
        );
    }
    let lobes = free.material.lobes().unwrap();
    let energy = glint::brdf::EnergyTable::with_defaults(&lobes);
    let worst = energy
        .albedo(&free.material.coefficients[0], 0.04)
        .into_iter()
        .fold(0.0f64, f64::max);
    println!(
        "no energy limit: residual {:?} vs {:?}; worst directional albedo {worst:.2}",
        free.material.fit.residual_rms, bound.material.fit.residual_rms
    );
    assert!(
        worst > 0.5,
        "the bright paint should need more than the physical bound"
    );
}
