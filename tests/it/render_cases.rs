//! The render tests' cases (a baked mesh under a map, the fitted sample material, one sharp lobe,
//! PRT and Monte Carlo pairs), shared by tests/it/render.rs and examples/render_studies.rs.
#![allow(dead_code)] // each of the two users takes a different subset

use crate::common;

use glint::bake::{BakeSettings, Baker};
use glint::env::EnvMap;
use glint::fit::run::{Baked, FitSettings, fit};
use glint::light::LightSums;
use glint::render::prt::{Prt, PrtSettings, Shading, Specular};
use glint::render::reference::{ExactMaterial, render_reference};
use glint::render::table::{PhPyramid, default_resolution};
use glint::scene::Scene;

pub struct Case {
    /// The baked scene (its mesh refined when the bake refined it).
    pub scene: Scene,
    pub env: EnvMap,
    pub baker_offset: f64,
    pub bake: glint::bake::Bake,
    pub tangents: Option<Vec<glam::Vec4>>,
    pub set: glint::sphere::DirectionSet,
    pub tree: glint::sphere::LightTree,
}

/// The mesh baked as imported.
pub fn case(mesh: &str, env: &str) -> Case {
    case_with(mesh, env, false)
}

/// With `refined`, baked as `glint bake` does: the mesh refined where visibility changes (decision
/// (e)).
pub fn case_with(mesh: &str, env: &str, refined: bool) -> Case {
    case_at(
        &common::assets().join(format!("glb/{mesh}.glb")),
        &common::assets().join(format!("hdr/small/{env}.exr")),
        refined,
    )
}

/// [`case_with`] for a scene and an environment given by path.
pub fn case_at(mesh: &std::path::Path, env: &std::path::Path, refined: bool) -> Case {
    let scene = glint::scene::import(mesh).unwrap();
    let env = glint::env::load(env).unwrap();
    let baker = Baker::new(&scene, &env, BakeSettings::default()).unwrap();
    let bake = if refined {
        baker.bake_refined(None, &|_| {})
    } else {
        baker.bake_all(None, &|_| {})
    };
    let offset = baker.ray_offset();
    let (set, tree) = (baker.set.clone(), baker.tree.clone());
    drop(baker);
    let scene = bake.scene(&scene).unwrap();
    let (_, tangents, _) = glint::bake::decisions::decide_frames(&scene.mesh);
    Case {
        scene,
        env,
        baker_offset: offset,
        bake,
        tangents,
        set,
        tree,
    }
}

pub const STROKES: &str = include_str!("../../samples/strokes/bunny-highlight.json");

/// Fits the sample strokes (a highlight painted on the default view) and returns the material.
pub fn fitted(c: &Case) -> glint::fit::material::Material {
    fitted_with(c, STROKES)
}

/// The material fitted to the strokes `strokes` (a stroke file's JSON) in case `c`.
pub fn fitted_with(c: &Case, strokes: &str) -> glint::fit::material::Material {
    let views = glint::fit::strokes::parse(strokes).unwrap();
    let outcome = fit(
        &Baked {
            scene: &c.scene,
            env: &c.env,
            cuts: &c.bake.cuts,
            resolution: c.bake.decisions.resolution,
            tangents: c.tangents.as_deref(),
            anisotropic: c.bake.decisions.anisotropic,
        },
        &views,
        &FitSettings::default(),
    )
    .unwrap();
    let m = outcome.material;
    assert!(
        m.coefficients.iter().flatten().any(|&x| x > 0.0),
        "the strokes must produce a specular lobe"
    );
    m
}

/// Errors of one comparison, relative RMSE over the object's pixels.
pub struct Errors {
    pub prt_vs_mc: f64,
    pub prt_vs_transfer: f64,
    pub transfer_vs_mc: f64,
    pub table_vs_exact: f64,
    pub mc_noise: f64,
}

pub fn compare(mesh: &str, w: u32, h: u32) -> Errors {
    let c = case_with(mesh, "studio_512", true);
    // The truth is rendered on the mesh as imported (the refinement does not move the surface).
    let imported = glint::scene::import(&common::assets().join(format!("glb/{mesh}.glb"))).unwrap();
    let (_, imported_tangents, _) = glint::bake::decisions::decide_frames(&imported.mesh);
    let m = fitted(&c);
    let lobes = m.lobes().unwrap();
    let coefficients = [
        m.coefficients[0].as_slice(),
        m.coefficients[1].as_slice(),
        m.coefficients[2].as_slice(),
    ];
    let camera = &c.scene.cameras[0];
    let light = LightSums::new(&c.env, &c.set, &c.tree, 0.0);
    let prt = Prt::new(
        &c.scene.mesh,
        &c.bake.cuts,
        &c.tree,
        c.tangents.as_deref(),
        PrtSettings::default(),
    );
    let table = PhPyramid::build(&lobes, coefficients, default_resolution(lobes.lambda()));
    let t0 = std::time::Instant::now();
    let tab = prt.render(
        &light,
        camera,
        w,
        h,
        &Shading {
            rho_d: m.rho_d,
            f0: m.f0,
            specular: Specular::Table(&table),
        },
    );
    let frame = t0.elapsed().as_secs_f64();
    let exact = prt.render(
        &light,
        camera,
        w,
        h,
        &Shading {
            rho_d: m.rho_d,
            f0: m.f0,
            specular: Specular::Exact {
                lobes: &lobes,
                coefficients,
            },
        },
    );
    // The per-pixel transfer render (same cuts, T·c + ρd E/π): what the PRT frame approximates.
    let ctx = glint::transfer::TransferContext::new(
        &c.scene.mesh,
        &c.bake.cuts,
        &c.tree,
        &lobes,
        c.tangents.as_deref(),
        None,
    );
    let t = ctx.compute(&light, camera, w, h, m.f0);
    let mut transfer = glint::render::Image::new(w, h);
    for (p, v) in t.pixels.iter().zip(t.render(m.rho_d, coefficients)) {
        transfer.set(p.x, p.y, v.map(|x| x as f32));
    }
    let t0 = std::time::Instant::now();
    let material = ExactMaterial {
        lobes: &lobes,
        coefficients,
        rho_d: m.rho_d,
        f0: m.f0,
    };
    let tracer = glint::bake::Tracer::new(&imported.mesh);
    let mc = render_reference(
        &imported.mesh,
        imported_tangents.as_deref(),
        &tracer,
        c.baker_offset,
        &c.env,
        0.0,
        material,
        camera,
        w,
        h,
        4096,
        7,
    );
    let mc_secs = t0.elapsed().as_secs_f64();
    // The reference's own noise: a second 4096-spp render with another seed (the difference of two
    // is √2 × the noise of one).
    let mc2 = render_reference(
        &imported.mesh,
        imported_tangents.as_deref(),
        &tracer,
        c.baker_offset,
        &c.env,
        0.0,
        material,
        camera,
        w,
        h,
        4096,
        8,
    );
    let diffuse_only = prt.render(
        &light,
        camera,
        w,
        h,
        &Shading {
            rho_d: m.rho_d,
            f0: m.f0,
            specular: Specular::None,
        },
    );
    // The BRDF once per partition node (merged runs, the default) against once per run.
    let per_run = Prt::new(
        &c.scene.mesh,
        &c.bake.cuts,
        &c.tree,
        c.tangents.as_deref(),
        PrtSettings {
            merge_runs: false,
            ..PrtSettings::default()
        },
    )
    .render(
        &light,
        camera,
        w,
        h,
        &Shading {
            rho_d: m.rho_d,
            f0: m.f0,
            specular: Specular::Table(&table),
        },
    );
    let merged_vs_per_run = tab.relative_rmse(&per_run).unwrap();
    println!(
        "{mesh}: merged runs vs the BRDF per run {merged_vs_per_run:.5}, per run vs MC {:.4}",
        per_run.relative_rmse(&mc).unwrap()
    );
    assert!(
        merged_vs_per_run < 0.005,
        "{mesh}: merged runs {merged_vs_per_run} off the per-run frame"
    );
    let e = Errors {
        prt_vs_mc: tab.relative_rmse(&mc).unwrap(),
        prt_vs_transfer: tab.relative_rmse(&transfer).unwrap(),
        transfer_vs_mc: transfer.relative_rmse(&mc).unwrap(),
        table_vs_exact: tab.relative_rmse(&exact).unwrap(),
        mc_noise: mc2.relative_rmse(&mc).unwrap() / 2f64.sqrt(),
    };
    let e_diffuse = diffuse_only.relative_rmse(&mc).unwrap();
    println!(
        "{mesh} {w}x{h}: {} baked vertices ({}), {} object pixels, shading subdivision {}, PRT frame {frame:.3} s, MC {mc_secs:.1} s; relative RMSE: PRT vs MC {:.4}, PRT vs per-pixel transfer {:.4}, transfer vs MC {:.4}, table vs exact lobes {:.5}, MC noise {:.4}, diffuse-only vs MC {e_diffuse:.3}",
        c.scene.mesh.positions.len(),
        c.bake.decisions.refine_reason,
        tab.covered_count(),
        prt.shading_mesh(camera, w, h).subdivision,
        e.prt_vs_mc,
        e.prt_vs_transfer,
        e.transfer_vs_mc,
        e.table_vs_exact,
        e.mc_noise
    );
    assert!(
        e_diffuse > 0.3,
        "the specular term must matter in this comparison (diffuse-only is {e_diffuse} off)"
    );
    assert!(e.mc_noise < 0.015, "reference noise {}", e.mc_noise);
    assert!(
        e.table_vs_exact <= 0.005,
        "{mesh}: table vs exact lobes {} > 0.5 %",
        e.table_vs_exact
    );
    e
}

/// The default PRT frame, the vertex-only PRT frame and the per-pixel transfer render of `m` in the
/// case's first camera.
pub fn prt_and_transfer(
    c: &Case,
    m: &glint::fit::material::Material,
    w: u32,
    h: u32,
) -> (
    glint::render::Image,
    glint::render::Image,
    glint::render::Image,
) {
    let lobes = m.lobes().unwrap();
    let coefficients = [
        m.coefficients[0].as_slice(),
        m.coefficients[1].as_slice(),
        m.coefficients[2].as_slice(),
    ];
    let camera = &c.scene.cameras[0];
    let light = LightSums::new(&c.env, &c.set, &c.tree, 0.0);
    let table = PhPyramid::build(&lobes, coefficients, default_resolution(lobes.lambda()));
    let shading = Shading {
        rho_d: m.rho_d,
        f0: m.f0,
        specular: Specular::Table(&table),
    };
    let prt = Prt::new(
        &c.scene.mesh,
        &c.bake.cuts,
        &c.tree,
        c.tangents.as_deref(),
        PrtSettings::default(),
    )
    .render(&light, camera, w, h, &shading);
    let prt_v = Prt::new(
        &c.scene.mesh,
        &c.bake.cuts,
        &c.tree,
        c.tangents.as_deref(),
        PrtSettings {
            max_edge_px: 0.0,
            per_pixel: false,
            ..PrtSettings::default()
        },
    )
    .render(&light, camera, w, h, &shading);
    let ctx = glint::transfer::TransferContext::new(
        &c.scene.mesh,
        &c.bake.cuts,
        &c.tree,
        &lobes,
        c.tangents.as_deref(),
        None,
    );
    let t = ctx.compute(&light, camera, w, h, m.f0);
    let mut transfer = glint::render::Image::new(w, h);
    for (p, v) in t.pixels.iter().zip(t.render(m.rho_d, coefficients)) {
        transfer.set(p.x, p.y, v.map(|x| x as f32));
    }
    (prt, prt_v, transfer)
}

/// Relative RMSE of `a` against `b` over the pixels both cover where `mask` holds (all with
/// `None`): the accuracy matrix's measure (`glint::accuracy::masked_rel_rmse`).
pub fn rmse_where(
    a: &glint::render::Image,
    b: &glint::render::Image,
    mask: Option<&[bool]>,
) -> f64 {
    let all;
    let mask = match mask {
        Some(m) => m,
        None => {
            all = vec![true; b.pixels.len()];
            &all
        }
    };
    glint::accuracy::masked_rel_rmse(a, b, mask).0
}

/// One sharp ring lobe along the normal (isotropic-24 at the paper's σ, λ = 81, only θ_j = 0 set,
/// scaled to a directional albedo of at most 0.9), ρd = 0.05, F0 = 0.04.
pub fn one_sharp_lobe() -> glint::fit::material::Material {
    use glint::sphere::srbf::{PAPER_SIGMA, lambda_from_sigma};
    let lobes = glint::sphere::LobeSet::new(
        glint::sphere::LobeLayout::Isotropic { count: 24 },
        lambda_from_sigma(PAPER_SIGMA).unwrap(),
    )
    .unwrap();
    let mut c = vec![0.0; lobes.len()];
    c[0] = 1.0;
    let albedo = glint::fit::energy_cache::table(&lobes)
        .albedo(&c, 0.04)
        .into_iter()
        .fold(0.0, f64::max);
    c[0] = 0.9 / albedo;
    glint::fit::material::Material::new(
        &lobes,
        PAPER_SIGMA,
        [c.clone(), c.clone(), c],
        [0.05; 3],
        0.04,
        Default::default(),
    )
}

/// PRT (default settings, tabulated p) and Monte Carlo images of `m` for a case, a camera and a
/// rotation, the reference on the mesh as imported (`imported`).
pub struct Pair {
    pub prt: glint::render::Image,
    pub mc: glint::render::Image,
    pub prt_secs: f64,
    pub mc_secs: f64,
}

#[allow(clippy::too_many_arguments)]
pub fn prt_and_mc(
    c: &Case,
    imported: &glint::scene::Mesh,
    m: &glint::fit::material::Material,
    camera: &glint::scene::Camera,
    rotation_deg: f64,
    w: u32,
    h: u32,
    spp: u32,
    settings: PrtSettings,
) -> Pair {
    let lobes = m.lobes().unwrap();
    let coefficients = [
        m.coefficients[0].as_slice(),
        m.coefficients[1].as_slice(),
        m.coefficients[2].as_slice(),
    ];
    let rotation = rotation_deg.to_radians();
    let light = LightSums::new(&c.env, &c.set, &c.tree, rotation);
    let prt = Prt::new(
        &c.scene.mesh,
        &c.bake.cuts,
        &c.tree,
        c.tangents.as_deref(),
        settings,
    );
    let table = PhPyramid::build(&lobes, coefficients, default_resolution(lobes.lambda()));
    let t0 = std::time::Instant::now();
    let img = prt.render(
        &light,
        camera,
        w,
        h,
        &Shading {
            rho_d: m.rho_d,
            f0: m.f0,
            specular: Specular::Table(&table),
        },
    );
    let prt_secs = t0.elapsed().as_secs_f64();
    let t0 = std::time::Instant::now();
    let mc = mc_render(c, imported, m, camera, rotation_deg, (w, h), spp, 7);
    Pair {
        prt: img,
        mc,
        prt_secs,
        mc_secs: t0.elapsed().as_secs_f64(),
    }
}

/// The Monte Carlo reference of [`prt_and_mc`] with its own seed (a second seed estimates the
/// reference's noise).
#[allow(clippy::too_many_arguments)]
pub fn mc_render(
    c: &Case,
    imported: &glint::scene::Mesh,
    m: &glint::fit::material::Material,
    camera: &glint::scene::Camera,
    rotation_deg: f64,
    (w, h): (u32, u32),
    spp: u32,
    seed: u64,
) -> glint::render::Image {
    let lobes = m.lobes().unwrap();
    let coefficients = [
        m.coefficients[0].as_slice(),
        m.coefficients[1].as_slice(),
        m.coefficients[2].as_slice(),
    ];
    let (_, tangents, _) = glint::bake::decisions::decide_frames(imported);
    let tracer = glint::bake::Tracer::new(imported);
    let material = ExactMaterial {
        lobes: &lobes,
        coefficients,
        rho_d: m.rho_d,
        f0: m.f0,
    };
    render_reference(
        imported,
        tangents.as_deref(),
        &tracer,
        c.baker_offset,
        &c.env,
        rotation_deg.to_radians(),
        material,
        camera,
        w,
        h,
        spp,
        seed,
    )
}
