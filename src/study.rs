//! The accuracy-against-time study: starting from the defaults, sweep each accuracy knob
//! in turn and measure what it costs and what it buys.
//!
//! Per setting: bake (visibility cuts), transfer (T for the fit view), fit (strokes → lobes), a CPU
//! PRT frame, the bake's memory, the frame's relative RMSE against a Monte Carlo truth (exact
//! visibility, exact lobes, the map itself), and the fit's residual on the fixed stroke set.
//!
//! Which material a row renders: knobs of the bake and of the renderer (direction set, visibility
//! cell, ε, cut cap, table resolution) render the *baseline* material (fitted once at the
//! defaults), so their errors share one Monte Carlo truth and differ only by the knob; knobs of the
//! fit (J, σ, fit resolution, the paper's row) render their own material against its own truth. The
//! `truth_spp` rows measure the reference itself: a render at that many samples per pixel against
//! the truth.
//!
//! Inputs: a scene, an environment, strokes, [`StudyOptions`]. Outputs: [`StudyRow`]s, the Pareto
//! front over (seconds, error, fit residual), and the report's text (CSV, SVG plot, Markdown) —
//! [`write_report`] is the only function here that writes files (atomically). Invariants: the
//! truths are seeded, so two runs give the same errors; times are wall-clock seconds on the machine
//! that ran it: every bake runs before anything else is timed, transfers and frames are the fastest
//! of three runs, and the energy table (once per lobe set and session) is reported apart from the
//! fit.

use crate::bake::{Bake, BakeSettings, Baker, Tracer};
use crate::env::EnvMap;
use crate::fit::material::Material;
use crate::fit::run::{Baked, FitSettings, camera_for, default_layout, fit};
use crate::fit::strokes::ViewStrokes;
use crate::light::LightSums;
use crate::render::{
    ExactMaterial, Image, PhPyramid, Prt, PrtSettings, Shading, Specular, render_reference, table,
};
use crate::scene::{Camera, Scene};
use crate::sphere::{LobeLayout, LobeSet, srbf};
use std::collections::HashMap;
use std::f64::consts::PI;
use std::path::Path;
use std::time::Instant;

/// How big a study to run.
#[derive(Debug, Clone)]
pub struct StudyOptions {
    /// Two values per knob, a small frame, a cheaper truth: for CI (under 2 minutes).
    pub quick: bool,
}

/// One measured setting.
#[derive(Debug, Clone, serde::Serialize)]
pub struct StudyRow {
    /// The knob varied (`default`, `paper` for the labelled rows).
    pub knob: String,
    pub value: String,
    /// True for the row that is the shipped default of this knob.
    pub is_default: bool,
    pub bake_secs: f64,
    pub transfer_secs: f64,
    /// The fit with the energy rows of its lobe set already integrated.
    pub fit_secs: f64,
    /// Integrating the energy rows of the row's lobe set (J, σ): once per lobe set and session
    /// ([`crate::fit::energy_cache::table`]), so not in [`StudyRow::total_secs`]; rows sharing a
    /// lobe set show the same figure.
    pub energy_table_secs: f64,
    pub frame_secs: f64,
    pub bake_bytes: usize,
    pub mean_cut_size: f64,
    /// The frame against the Monte Carlo truth (relative RMSE over object pixels).
    pub rel_rmse: f64,
    /// The fit's weighted residual RMS, mean over channels.
    pub residual: f64,
}

impl StudyRow {
    /// What a user waits for this setting: bake + transfer + fit + one frame (the energy table is a
    /// once-per-session cost and is reported apart).
    pub fn total_secs(&self) -> f64 {
        self.bake_secs + self.transfer_secs + self.fit_secs + self.frame_secs
    }
}

/// Why the study cannot run.
#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    #[error("bake: {0}")]
    Bake(#[from] crate::bake::BakeError),
    #[error("fit: {0}")]
    Fit(#[from] crate::fit::run::FitError),
    #[error("lobes: {0}")]
    Sphere(#[from] crate::sphere::SphereError),
    #[error("the strokes name no view")]
    NoView,
    #[error("writing {path}: {reason}")]
    Write { path: String, reason: String },
    #[error(transparent)]
    Scene(#[from] crate::scene::ImportError),
    #[error(transparent)]
    Env(#[from] crate::env::EnvError),
    #[error("{0}")]
    Input(String),
    #[error("{path}: {source}")]
    Strokes {
        path: String,
        source: crate::fit::strokes::StrokeError,
    },
}

/// Transfers and frames are timed this many times and the fastest kept: the first run of a process
/// pays for warming caches (the default row, measured first, looked 5-10 % slower than identical
/// rows measured later).
const TIMING_RUNS: usize = 3;

/// The last result of `runs` calls of `f` (at least one), and the seconds of the fastest call.
fn fastest_of<T>(runs: usize, mut f: impl FnMut() -> T) -> (T, f64) {
    let mut timed = || {
        let t0 = Instant::now();
        let r = f();
        (r, t0.elapsed().as_secs_f64())
    };
    let (mut result, mut best) = timed();
    for _ in 1..runs {
        let (r, secs) = timed();
        result = r;
        best = best.min(secs);
    }
    (result, best)
}

/// The settings of one row.
#[derive(Debug, Clone, PartialEq)]
struct Knobs {
    resolution: Option<usize>,
    /// None: decided (decision (d)).
    cell_deg: Option<f64>,
    epsilon: f64,
    max_cut: usize,
    /// Rounds of the bake's adaptive refinement (decision (e)).
    refine_rounds: u32,
    /// Boundary refinement of the cells; None: decided with the cell (decision (d)).
    boundary_levels: Option<u32>,
    layout: Option<LobeLayout>,
    sigma: f64,
    fit_size: Option<(u32, u32)>,
    table_resolution: Option<usize>,
    truth_spp: Option<u32>,
}

impl Knobs {
    fn defaults() -> Self {
        let b = BakeSettings::default();
        Self {
            resolution: None,
            cell_deg: b.cell_deg,
            epsilon: b.cut.epsilon,
            max_cut: b.cut.max_cut,
            refine_rounds: b.refine.rounds,
            boundary_levels: b.boundary_levels,
            layout: None,
            sigma: srbf::PAPER_SIGMA,
            fit_size: None,
            table_resolution: None,
            truth_spp: None,
        }
    }
    fn bake_key(&self) -> String {
        format!(
            "{:?}/{:?}/{}/{}/{}/{:?}",
            self.resolution,
            self.cell_deg,
            self.epsilon,
            self.max_cut,
            self.refine_rounds,
            self.boundary_levels
        )
    }
    fn changes_material(&self) -> bool {
        let d = Self::defaults();
        self.layout != d.layout || self.sigma != d.sigma || self.fit_size != d.fit_size
    }
}

struct BakeResult {
    bake: Bake,
    /// The scene with the baked (refined) mesh, which the cuts belong to.
    scene: Scene,
    secs: f64,
    set: crate::sphere::DirectionSet,
    tree: crate::sphere::LightTree,
    tangents: Option<Vec<glam::Vec4>>,
    offset: f64,
}

fn run_bake(scene: &Scene, env: &EnvMap, k: &Knobs) -> Result<BakeResult, StudyError> {
    let mut settings = BakeSettings {
        resolution: k.resolution,
        cell_deg: k.cell_deg,
        boundary_levels: k.boundary_levels,
        ..BakeSettings::default()
    };
    settings.cut.epsilon = k.epsilon;
    settings.cut.max_cut = k.max_cut;
    settings.refine.rounds = k.refine_rounds;
    let t0 = Instant::now();
    let baker = Baker::new(scene, env, settings)?;
    let bake = baker.bake_refined(None, &|_| {});
    let secs = t0.elapsed().as_secs_f64();
    let refined = bake.scene(scene)?;
    let (_, tangents, _) = crate::bake::decisions::decide_frames(&refined.mesh);
    Ok(BakeResult {
        bake,
        scene: refined,
        secs,
        set: baker.set.clone(),
        tree: baker.tree.clone(),
        tangents,
        offset: baker.ray_offset(),
    })
}

fn coefficient_slices(m: &Material) -> [&[f64]; 3] {
    [
        m.coefficients[0].as_slice(),
        m.coefficients[1].as_slice(),
        m.coefficients[2].as_slice(),
    ]
}

/// The rows a study sweeps: the defaults, then one knob at a time, then the paper's settings.
fn settings(
    quick: bool,
    anisotropic: bool,
    decided_resolution: usize,
    decided_cell: f64,
    decided_boundary: u32,
) -> Vec<(String, String, Knobs)> {
    let d = Knobs::defaults();
    let label = format!(
        "all defaults (decided: 6·{decided_resolution}² directions, {decided_cell}° cells, {decided_boundary} boundary levels)"
    );
    let mut rows = vec![("default".to_string(), label, d.clone())];
    let mut push = |knob: &str, value: String, k: Knobs| rows.push((knob.to_string(), value, k));
    // (In --quick, one value per knob and no paper row: J = 147 alone costs half a minute.)
    let pick =
        |full: &[f64], q: &[f64]| -> Vec<f64> { if quick { q.to_vec() } else { full.to_vec() } };
    let res_values: Vec<usize> = if quick {
        vec![decided_resolution / 2]
    } else {
        vec![decided_resolution / 2, decided_resolution * 2]
    };
    for n in res_values.into_iter().filter(|&n| n >= 8) {
        push(
            "direction_set_n",
            format!("{n} (6·n² = {} directions)", 6 * n * n),
            Knobs {
                resolution: Some(n),
                ..d.clone()
            },
        );
    }
    // The visibility cell around the decided one (decision (d)).
    for c in pick(&[22.5, 11.25, 5.625, 2.8125], &[22.5])
        .into_iter()
        .filter(|&c| c != decided_cell)
    {
        push(
            "visibility_cell_deg",
            format!("{c}"),
            Knobs {
                cell_deg: Some(c),
                ..d.clone()
            },
        );
    }
    // Boundary refinement of the cells at shadow edges, around the decided levels (decision (d)).
    for b in pick(&[0.0, 1.0, 2.0], &[])
        .into_iter()
        .filter(|&b| b as u32 != decided_boundary)
    {
        push(
            "boundary_levels",
            format!("{b}"),
            Knobs {
                boundary_levels: Some(b as u32),
                ..d.clone()
            },
        );
    }
    for e in pick(&[0.08, 0.005], &[0.08]) {
        push(
            "cut_epsilon",
            format!("{e}"),
            Knobs {
                epsilon: e,
                ..d.clone()
            },
        );
    }
    for m in pick(&[128.0, 4096.0], &[]) {
        push(
            "cut_cap",
            format!("{m}"),
            Knobs {
                max_cut: m as usize,
                ..d.clone()
            },
        );
    }
    for r in pick(&[0.0, 1.0], &[0.0])
        .into_iter()
        .filter(|&r| r as u32 != d.refine_rounds)
    {
        let label = if r == 0.0 {
            "0 (the mesh as imported)".to_string()
        } else {
            format!("{r}")
        };
        push(
            "refine_rounds",
            label,
            Knobs {
                refine_rounds: r as u32,
                ..d.clone()
            },
        );
    }
    let layouts: Vec<LobeLayout> = match (anisotropic, quick) {
        (true, false) => vec![LobeLayout::Hemicube { n: 5 }, LobeLayout::Hemicube { n: 9 }],
        (true, true) => vec![LobeLayout::Hemicube { n: 5 }],
        (false, false) => vec![
            LobeLayout::Isotropic { count: 12 },
            LobeLayout::Isotropic { count: 48 },
        ],
        (false, true) => vec![LobeLayout::Isotropic { count: 12 }],
    };
    for l in layouts {
        let j = l.count();
        push(
            "lobes_J",
            format!("{j} ({})", l.name()),
            Knobs {
                layout: Some(l),
                ..d.clone()
            },
        );
    }
    for s in pick(&[PI / 80.0, PI / 20.0], &[PI / 20.0]) {
        push(
            "sigma",
            format!("π/{:.0}", PI / s),
            Knobs {
                sigma: s,
                ..d.clone()
            },
        );
    }
    let fit_sizes: Vec<(u32, u32)> = if quick {
        vec![(40, 30)]
    } else {
        vec![(80, 60), (320, 240)]
    };
    for f in fit_sizes {
        push(
            "fit_resolution",
            format!("{}x{}", f.0, f.1),
            Knobs {
                fit_size: Some(f),
                ..d.clone()
            },
        );
    }
    for t in pick(&[64.0, 128.0, 512.0], &[64.0]) {
        push(
            "table_resolution",
            format!("{t}"),
            Knobs {
                table_resolution: Some(t as usize),
                ..d.clone()
            },
        );
    }
    for s in pick(&[64.0, 256.0, 1024.0], &[16.0, 64.0]) {
        push(
            "truth_spp",
            format!("{s}"),
            Knobs {
                truth_spp: Some(s as u32),
                ..d.clone()
            },
        );
    }
    // The paper: J = 147 (its hemicube needs a tangent field; a scene without one gets 147 rings),
    // σ = π/40, fit at 160×120. The paper's N_l = 192 energy rows are always in glint's set, which
    // adds 64 near-horizon rows and the normal (257 in all; method.md §9, tests/it/properties.rs).
    if quick {
        return rows;
    }
    let paper_layout = if anisotropic {
        LobeLayout::PAPER
    } else {
        LobeLayout::Isotropic { count: 147 }
    };
    let label = format!(
        "J 147 ({}), σ π/40, fit 160x120, N_l 192+1+64",
        paper_layout.name()
    );
    push(
        "paper",
        label,
        Knobs {
            layout: Some(paper_layout),
            sigma: srbf::PAPER_SIGMA,
            fit_size: Some((160, 120)),
            ..d
        },
    );
    rows
}

/// Runs the study. `progress(done, total, what)` is called before each row.
pub fn run(
    scene: &Scene,
    env: &EnvMap,
    strokes: &[ViewStrokes],
    options: &StudyOptions,
    progress: &dyn Fn(usize, usize, &str),
) -> Result<Vec<StudyRow>, StudyError> {
    let first = strokes.first().ok_or(StudyError::NoView)?;
    let (w, h) = if options.quick { (80, 60) } else { (160, 120) };
    let truth_spp: u32 = if options.quick { 256 } else { 4096 };
    let mut camera: Camera = camera_for(scene, &first.view, first.image_size)?;
    camera.aspect = w as f32 / h as f32;
    let tracer = Tracer::new(&scene.mesh);
    // The truth is rendered on the scene as imported (the refined meshes have the same surface).
    let (_, base_tangents, _) = crate::bake::decisions::decide_frames(&scene.mesh);

    let mut bakes: HashMap<String, BakeResult> = HashMap::new();
    let defaults = Knobs::defaults();
    let base = run_bake(scene, env, &defaults)?;
    let anisotropic = base.bake.decisions.anisotropic;
    let decided = base.bake.decisions.resolution;
    let decided_cell = base.bake.decisions.cell_deg;
    let decided_boundary = base.bake.decisions.boundary_levels;
    bakes.insert(defaults.bake_key(), base);
    let plan = settings(
        options.quick,
        anisotropic,
        decided,
        decided_cell,
        decided_boundary,
    );
    let mut baseline: Option<Material> = None;
    let mut truths: Vec<(Vec<u64>, Image)> = Vec::new();
    let mut fits: HashMap<String, (Material, f64, f64)> = HashMap::new();
    let mut tables: HashMap<String, f64> = HashMap::new();
    let mut rows = Vec::new();
    // Every bake first, before the truths' and transfers' large allocations: bakes timed after them
    // ran 2-3x slower than alone (bunny, 11.25° cells: 1.03 s in the study, 0.29 s alone).
    for (i, (knob, value, k)) in plan.iter().enumerate() {
        if let std::collections::hash_map::Entry::Vacant(slot) = bakes.entry(k.bake_key()) {
            progress(i, plan.len(), &format!("baking for {knob} = {value}"));
            slot.insert(run_bake(scene, env, k)?);
        }
    }
    for (i, (knob, value, k)) in plan.iter().enumerate() {
        progress(i, plan.len(), &format!("{knob} = {value}"));
        let b = &bakes[&k.bake_key()];
        // Fits are cached by everything they depend on: rows of renderer knobs reuse the
        // baseline's.
        let fit_key = format!(
            "{}/{:?}/{}/{:?}",
            k.bake_key(),
            k.layout,
            k.sigma,
            k.fit_size
        );
        // The energy rows of this lobe set, integrated once (and timed) before the fit is timed, so
        // that the first row of a lobe set does not carry the cost for the rest.
        let row_lobes = LobeSet::new(
            k.layout.unwrap_or_else(|| default_layout(anisotropic)),
            srbf::lambda_from_sigma(k.sigma)?,
        )?;
        let table_key = format!("{:?}/{}", row_lobes.layout(), k.sigma);
        let energy_table_secs = *tables.entry(table_key).or_insert_with(|| {
            let t0 = Instant::now();
            std::hint::black_box(crate::fit::energy_cache::table(&row_lobes));
            t0.elapsed().as_secs_f64()
        });
        if !fits.contains_key(&fit_key) {
            let fit_settings = FitSettings {
                layout: k.layout,
                sigma: k.sigma,
                fit_size: k.fit_size,
                ..FitSettings::default()
            };
            let t0 = Instant::now();
            let outcome = fit(
                &Baked {
                    scene: &b.scene,
                    env,
                    cuts: &b.bake.cuts,
                    resolution: b.bake.decisions.resolution,
                    tangents: b.tangents.as_deref(),
                    anisotropic,
                },
                strokes,
                &fit_settings,
            )?;
            let fit_total = t0.elapsed().as_secs_f64();
            // The transfer alone, for the first view at the fit resolution (fit_total includes it).
            let lobes = outcome.material.lobes()?;
            let light = LightSums::new(env, &b.set, &b.tree, 0.0);
            let ctx = crate::transfer::TransferContext::new(
                &b.scene.mesh,
                &b.bake.cuts,
                &b.tree,
                &lobes,
                b.tangents.as_deref(),
                None,
            );
            let (fw, fh) = outcome.views[0].fit_size;
            let (_, transfer_secs) = fastest_of(TIMING_RUNS, || {
                ctx.compute(
                    &light,
                    &outcome.views[0].camera,
                    fw,
                    fh,
                    outcome.material.f0,
                )
            });
            fits.insert(
                fit_key.clone(),
                (
                    outcome.material,
                    transfer_secs,
                    (fit_total - transfer_secs).max(0.0),
                ),
            );
        }
        let (fitted, transfer_secs, fit_secs) = fits[&fit_key].clone();
        let light = LightSums::new(env, &b.set, &b.tree, 0.0);
        let residual = fitted.fit.residual_rms.iter().sum::<f64>() / 3.0;
        let first = baseline.get_or_insert_with(|| fitted.clone());
        let material = if k.changes_material() {
            &fitted
        } else {
            &*first
        };
        let mlobes = material.lobes()?;
        let coefficients = coefficient_slices(material);
        // The truth of this material (cached by its coefficients' bits).
        let key: Vec<u64> = material
            .coefficients
            .iter()
            .flatten()
            .chain(material.rho_d.iter())
            .map(|x| x.to_bits())
            .collect();
        let index = match truths.iter().position(|(k2, _)| *k2 == key) {
            Some(i) => i,
            None => {
                let exact = ExactMaterial {
                    lobes: &mlobes,
                    coefficients,
                    rho_d: material.rho_d,
                    f0: material.f0,
                };
                let truth = render_reference(
                    &scene.mesh,
                    base_tangents.as_deref(),
                    &tracer,
                    b.offset,
                    env,
                    0.0,
                    exact,
                    &camera,
                    w,
                    h,
                    truth_spp,
                    1,
                );
                truths.push((key.clone(), truth));
                truths.len() - 1
            }
        };
        let truth = &truths[index].1;
        let (frame_secs, rel_rmse) = match k.truth_spp {
            Some(spp) => {
                let exact = ExactMaterial {
                    lobes: &mlobes,
                    coefficients,
                    rho_d: material.rho_d,
                    f0: material.f0,
                };
                let t0 = Instant::now();
                let img = render_reference(
                    &scene.mesh,
                    base_tangents.as_deref(),
                    &tracer,
                    b.offset,
                    env,
                    0.0,
                    exact,
                    &camera,
                    w,
                    h,
                    spp,
                    2,
                );
                (
                    t0.elapsed().as_secs_f64(),
                    img.relative_rmse(truth).unwrap_or(f64::NAN),
                )
            }
            None => {
                let resolution = k
                    .table_resolution
                    .unwrap_or_else(|| table::default_resolution(mlobes.lambda()));
                let frame = || {
                    let tab = PhPyramid::build(&mlobes, coefficients, resolution);
                    let prt = Prt::new(
                        &b.scene.mesh,
                        &b.bake.cuts,
                        &b.tree,
                        b.tangents.as_deref(),
                        PrtSettings::default(),
                    );
                    prt.render(
                        &light,
                        &camera,
                        w,
                        h,
                        &Shading {
                            rho_d: material.rho_d,
                            f0: material.f0,
                            specular: Specular::Table(&tab),
                        },
                    )
                };
                let (img, secs) = fastest_of(TIMING_RUNS, frame);
                (secs, img.relative_rmse(truth).unwrap_or(f64::NAN))
            }
        };
        rows.push(StudyRow {
            knob: knob.clone(),
            value: value.clone(),
            is_default: knob == "default",
            bake_secs: b.secs,
            transfer_secs,
            fit_secs,
            energy_table_secs,
            frame_secs,
            bake_bytes: b.bake.cuts.bytes(),
            mean_cut_size: b.bake.cuts.mean_cut_size(),
            rel_rmse,
            residual,
        });
    }
    progress(plan.len(), plan.len(), "done");
    Ok(rows)
}

/// Which rows are on the Pareto front of (total seconds, rel_rmse, residual): no other row is at
/// least as good in all three and strictly better in one. The fit residual is the third objective
/// because a setting can render closer to the truth by fitting the strokes worse (a wider σ does).
/// The `truth_spp` rows measure the reference, not the product, and are left out.
pub fn pareto_front(rows: &[StudyRow]) -> Vec<bool> {
    let counts =
        |r: &StudyRow| r.knob != "truth_spp" && r.rel_rmse.is_finite() && r.residual.is_finite();
    rows.iter()
        .map(|r| {
            counts(r)
                && !rows.iter().any(|o| {
                    counts(o)
                        && o.total_secs() <= r.total_secs()
                        && o.rel_rmse <= r.rel_rmse
                        && o.residual <= r.residual
                        && (o.total_secs() < r.total_secs()
                            || o.rel_rmse < r.rel_rmse
                            || o.residual < r.residual)
                })
        })
        .collect()
}

/// `study.csv`: one row per setting.
pub fn csv(rows: &[StudyRow], front: &[bool]) -> String {
    let mut s = String::from(
        "knob,value,bake_secs,transfer_secs,fit_secs,energy_table_secs,frame_secs,total_secs,bake_bytes,mean_cut_size,rel_rmse,residual,pareto\n",
    );
    for (r, p) in rows.iter().zip(front) {
        s += &format!(
            "{},\"{}\",{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{},{:.1},{:.5},{:.6},{}\n",
            r.knob,
            r.value.replace('"', "'"),
            r.bake_secs,
            r.transfer_secs,
            r.fit_secs,
            r.energy_table_secs,
            r.frame_secs,
            r.total_secs(),
            r.bake_bytes,
            r.mean_cut_size,
            r.rel_rmse,
            r.residual,
            p
        );
    }
    s
}

/// `study.md`: the table, Pareto rows in bold.
pub fn markdown(rows: &[StudyRow], front: &[bool], title: &str) -> String {
    let mut s = format!(
        "# {title}\n\n| knob | value | bake s | transfer s | fit s | frame s | total s | energy table s (once per J, σ) | bake MB | mean cut | rel. RMSE vs MC | fit residual | Pareto |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n"
    );
    for (r, p) in rows.iter().zip(front) {
        let b = if *p { "**" } else { "" };
        s += &format!(
            "| {b}{}{b} | {b}{}{b} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} | {:.2} | {:.2} | {:.0} | {:.2} % | {:.5} | {} |\n",
            r.knob,
            r.value,
            r.bake_secs,
            r.transfer_secs,
            r.fit_secs,
            r.frame_secs,
            r.total_secs(),
            r.energy_table_secs,
            r.bake_bytes as f64 / 1e6,
            r.mean_cut_size,
            100.0 * r.rel_rmse,
            r.residual,
            if *p { "yes" } else { "" }
        );
    }
    s
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// `study.svg`: relative RMSE against total seconds (log scale), one colour per knob, the Pareto
/// front joined by a line, the default ringed.
///
/// Written by hand, not with a plotting crate: one scatter plot with a log axis is ~130 lines of
/// SVG text and needs no dependency, where `plotters` would add its crates (and fonts) to every
/// build of the library for this one chart; the test below checks the file parses and escapes.
pub fn svg(rows: &[StudyRow], front: &[bool], title: &str) -> String {
    let (w, h, ml, mr, mt, mb) = (760.0, 480.0, 70.0, 220.0, 40.0, 50.0);
    let pts: Vec<(usize, f64, f64)> = rows
        .iter()
        .enumerate()
        .filter(|(_, r)| r.rel_rmse.is_finite() && r.total_secs() > 0.0 && r.knob != "truth_spp")
        .map(|(i, r)| (i, r.total_secs(), 100.0 * r.rel_rmse))
        .collect();
    let (tmin, tmax) = pts
        .iter()
        .fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.1), a.1.max(p.1)));
    let emax = pts.iter().fold(0.0f64, |a, p| a.max(p.2)) * 1.1 + 1e-9;
    let (lt0, lt1) = (
        (tmin * 0.8).log10(),
        (tmax * 1.25).log10().max((tmin * 0.8).log10() + 0.1),
    );
    let x = |t: f64| ml + (t.log10() - lt0) / (lt1 - lt0) * (w - ml - mr);
    let y = |e: f64| h - mb - e / emax * (h - mt - mb);
    let palette = [
        "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
        "#bcbd22", "#17becf", "#000000",
    ];
    let mut knobs: Vec<&str> = Vec::new();
    for r in rows {
        if r.knob != "truth_spp" && !knobs.contains(&r.knob.as_str()) {
            knobs.push(&r.knob);
        }
    }
    let colour = |k: &str| palette[knobs.iter().position(|x| *x == k).unwrap_or(0) % palette.len()];
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n<text x=\"{ml}\" y=\"22\" font-size=\"15\">{}</text>\n",
        escape(title)
    );
    s += &format!(
        "<line x1=\"{ml}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"black\"/>\n<line x1=\"{ml}\" y1=\"{mt}\" x2=\"{ml}\" y2=\"{}\" stroke=\"black\"/>\n",
        h - mb,
        w - mr,
        h - mb,
        h - mb
    );
    // Decade and half-decade ticks on x, five ticks on y.
    let mut t = 10f64.powf(lt0.floor());
    while t <= 10f64.powf(lt1) {
        for m in [1.0, 2.0, 5.0] {
            let v = t * m;
            if v.log10() >= lt0 && v.log10() <= lt1 {
                s += &format!(
                    "<line x1=\"{0:.1}\" y1=\"{1}\" x2=\"{0:.1}\" y2=\"{2}\" stroke=\"#ccc\"/><text x=\"{0:.1}\" y=\"{3}\" text-anchor=\"middle\">{4}</text>\n",
                    x(v),
                    mt,
                    h - mb,
                    h - mb + 16.0,
                    v
                );
            }
        }
        t *= 10.0;
    }
    for i in 0..=5 {
        let e = emax * i as f64 / 5.0;
        s += &format!(
            "<line x1=\"{ml}\" y1=\"{0:.1}\" x2=\"{1}\" y2=\"{0:.1}\" stroke=\"#eee\"/><text x=\"{2}\" y=\"{3:.1}\" text-anchor=\"end\">{e:.1}</text>\n",
            y(e),
            w - mr,
            ml - 6.0,
            y(e) + 4.0
        );
    }
    s += &format!(
        "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">bake + transfer + fit + frame (s, log scale)</text>\n",
        (ml + w - mr) / 2.0,
        h - 12.0
    );
    s += &format!(
        "<text x=\"16\" y=\"{}\" transform=\"rotate(-90 16 {})\" text-anchor=\"middle\">frame vs Monte Carlo, relative RMSE (%)</text>\n",
        (mt + h - mb) / 2.0,
        (mt + h - mb) / 2.0
    );
    let mut f: Vec<&(usize, f64, f64)> = pts.iter().filter(|p| front[p.0]).collect();
    f.sort_by(|a, b| a.1.total_cmp(&b.1));
    if f.len() > 1 {
        let path: Vec<String> = f
            .iter()
            .map(|p| format!("{:.1},{:.1}", x(p.1), y(p.2)))
            .collect();
        s += &format!(
            "<polyline points=\"{}\" fill=\"none\" stroke=\"#444\" stroke-dasharray=\"4 3\"/>\n",
            path.join(" ")
        );
    }
    for &(i, t, e) in &pts {
        let r = &rows[i];
        s += &format!(
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"{}\" fill=\"{}\"><title>{}: {} ({:.2} s, {:.2} %)</title></circle>\n",
            x(t),
            y(e),
            if front[i] { 6 } else { 4 },
            colour(&r.knob),
            escape(&r.knob),
            escape(&r.value),
            t,
            e
        );
        if r.is_default {
            s += &format!(
                "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"10\" fill=\"none\" stroke=\"black\"/>\n",
                x(t),
                y(e)
            );
        }
    }
    for (k, name) in knobs.iter().enumerate() {
        let ly = mt + 18.0 * k as f64;
        s += &format!(
            "<circle cx=\"{}\" cy=\"{ly}\" r=\"5\" fill=\"{}\"/><text x=\"{}\" y=\"{}\">{}</text>\n",
            w - mr + 16.0,
            colour(name),
            w - mr + 26.0,
            ly + 4.0,
            escape(name)
        );
    }
    let ly = mt + 18.0 * knobs.len() as f64 + 10.0;
    s += &format!(
        "<line x1=\"{}\" y1=\"{ly}\" x2=\"{}\" y2=\"{ly}\" stroke=\"#444\" stroke-dasharray=\"4 3\"/><text x=\"{}\" y=\"{}\">Pareto front</text>\n",
        w - mr + 8.0,
        w - mr + 24.0,
        w - mr + 26.0,
        ly + 4.0
    );
    s += &format!(
        "<circle cx=\"{}\" cy=\"{}\" r=\"8\" fill=\"none\" stroke=\"black\"/><text x=\"{}\" y=\"{}\">the defaults</text>\n</svg>\n",
        w - mr + 16.0,
        ly + 20.0,
        w - mr + 26.0,
        ly + 24.0
    );
    s
}

/// Writes study.csv, study.svg and study.md into `dir` (created), each atomically.
pub fn write_report(
    dir: &Path,
    rows: &[StudyRow],
    title: &str,
) -> Result<Vec<std::path::PathBuf>, StudyError> {
    let front = pareto_front(rows);
    std::fs::create_dir_all(dir).map_err(|e| StudyError::Write {
        path: dir.display().to_string(),
        reason: e.to_string(),
    })?;
    let mut written = Vec::new();
    for (name, text) in [
        ("study.csv", csv(rows, &front)),
        ("study.svg", svg(rows, &front, title)),
        ("study.md", markdown(rows, &front, title)),
    ] {
        let path = dir.join(name);
        glint_exporters::write_atomic(&path, text.as_bytes()).map_err(|e| StudyError::Write {
            path: path.display().to_string(),
            reason: e.to_string(),
        })?;
        written.push(path);
    }
    Ok(written)
}

/// What `glint study` did: the files written and a one-line summary of the defaults.
pub struct StudyReport {
    pub written: Vec<std::path::PathBuf>,
    pub summary: Option<String>,
}

/// `glint study`: reads the scene, the map and the strokes, sweeps ([`run`]) and writes study.csv,
/// study.svg and study.md into `out` ([`write_report`]).
pub fn run_study(
    scene_path: &Path,
    env_path: &Path,
    strokes_path: &Path,
    quick: bool,
    out: &Path,
    progress: &dyn Fn(usize, usize, &str),
) -> Result<StudyReport, StudyError> {
    let scene = crate::scene::import(scene_path)?;
    let env = crate::env::load(env_path)?;
    let text = std::fs::read_to_string(strokes_path)
        .map_err(|e| StudyError::Input(format!("cannot read {}: {e}", strokes_path.display())))?;
    let strokes = crate::fit::strokes::parse(&text).map_err(|source| StudyError::Strokes {
        path: strokes_path.display().to_string(),
        source,
    })?;
    let start = Instant::now();
    let rows = run(&scene, &env, &strokes, &StudyOptions { quick }, progress)?;
    let name = |p: &Path| {
        p.file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    let title = format!(
        "glint study: {} under {}{} — {} settings, {:.0} s on {} threads",
        name(scene_path),
        name(env_path),
        if quick { " (quick)" } else { "" },
        rows.len(),
        start.elapsed().as_secs_f64(),
        rayon::current_num_threads()
    );
    let written = write_report(out, &rows, &title)?;
    let front = pareto_front(&rows);
    let on_front = front.iter().filter(|p| **p).count();
    let summary = rows.iter().find(|r| r.is_default).map(|r| {
        format!("defaults: {:.2} s, {:.2} % against Monte Carlo; {on_front} of {} settings on the Pareto front", r.total_secs(), 100.0 * r.rel_rmse, rows.len())
    });
    Ok(StudyReport { written, summary })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(knob: &str, t: f64, e: f64) -> StudyRow {
        StudyRow {
            knob: knob.into(),
            value: "v".into(),
            is_default: false,
            bake_secs: t,
            transfer_secs: 0.0,
            fit_secs: 0.0,
            energy_table_secs: 0.0,
            frame_secs: 0.0,
            bake_bytes: 0,
            mean_cut_size: 0.0,
            rel_rmse: e,
            residual: 0.0,
        }
    }

    #[test]
    fn a_row_that_fits_the_strokes_better_is_not_dominated() {
        let mut slow = row("a", 2.0, 0.05);
        slow.residual = 1.0;
        let mut fast = row("sigma", 1.0, 0.04);
        fast.residual = 1.1;
        let mut worse = row("b", 3.0, 0.06);
        worse.residual = 1.0;
        assert_eq!(pareto_front(&[slow, fast, worse]), vec![true, true, false]);
    }

    #[test]
    fn pareto_front_keeps_only_undominated_rows() {
        let rows = [
            row("a", 1.0, 0.10),
            row("b", 2.0, 0.05),
            row("c", 3.0, 0.07),
            row("d", 0.5, 0.20),
            row("truth_spp", 0.1, 0.0),
            row("e", 2.0, 0.05),
        ];
        // c is dominated by b; the truth row is excluded; equal rows b and e both stay.
        assert_eq!(
            pareto_front(&rows),
            vec![true, true, false, true, false, true]
        );
    }

    #[test]
    fn report_texts_hold_every_row() {
        let rows = [row("a", 1.0, 0.10), row("b", 2.0, 0.05)];
        let front = pareto_front(&rows);
        let c = csv(&rows, &front);
        assert_eq!(c.lines().count(), 3);
        assert!(c.starts_with("knob,value,"));
        assert!(c.lines().next().unwrap().contains("rel_rmse") && c.contains("residual"));
        let s = svg(&rows, &front, "t <&>");
        assert_eq!(
            s.matches("<circle").count(),
            2 + 2 + 1,
            "two points, two legend dots, the defaults' legend ring"
        );
        assert!(s.contains("t &lt;&amp;&gt;"));
        assert_eq!(
            markdown(&rows, &front, "t").matches("\n|").count(),
            4,
            "header, separator, two rows"
        );
    }
}
