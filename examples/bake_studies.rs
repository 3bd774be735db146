//! Bake studies: how the bake's visibility could be sampled, simulated with the bake's own tracer
//! and printed (a developer tool behind figures in docs/benchmarks.md). Run one by name, e.g.
//! `cargo run --release --features studies --example bake_studies -- edge_schemes dragon_100k
//! interior_1k 400`.
//!
//! `edge_schemes MESH MAP [PROBES]`: ways of refining shadow edges on a cube map of 128
//! directions a side, each face on its own (no neighbours across a face's border), from cells of
//! 16×16 directions (11.25°) down to 2×2 in three levels, over each probe vertex's whole
//! hemisphere, with no light budget and no cone tests:
//! - quarters: a ray along each cell's centre; a cell with a neighbour (of its 8) of the other
//!   visibility is traced again as its 4 quarters, as the bake's boundary refinement does
//!   (`bake::cuts` rule 6); each direction takes the visibility of the finest cell that holds it;
//! - corners: a ray at each block's corners; a block whose 4 corners disagree is traced at its
//!   centre and its edges' midpoints (points shared with its neighbours are traced once) and split
//!   in 4; each direction takes the visibility of the nearest corner of the finest block that
//!   holds it;
//! - bisect after 0, 1 or 2 levels: the quarters for that many levels, then, between each pair of
//!   neighbouring cells of unlike visibility, the segment between their rays bisected down to the
//!   finest cell, each direction near such a pair taking the visibility of the nearest point
//!   traced.
//!
//! Each is compared with a ray per direction, weighted by solid angle × cosine (the geometry
//! alone) and by that × the map's luminance.
//!
//! `flat_cells MESH MAP`: the bake's boundary refinement done on flat per-face grids of square
//! cells instead of the light tree (the same sizes as `edge_schemes`, each face on its own), with
//! the bake's light budget β over the vertex's hemisphere (the rotation-worst luminance per
//! elevation), edge quarters and the first level's other quarters, and the cut merged bottom-up
//! over each face's quadtree within ε; against the bake's own cuts of the same 400 vertices
//! (`Baker::point_cuts` at 128 directions a side, one vertex at a time), both on one thread,
//! median of 3: rays, microseconds per vertex (the flat pipeline's time in the tracer apart), cut
//! entries, and the error against a ray per direction weighted by solid angle × cosine × the map's
//! luminance. What a rewrite of the cut's bookkeeping on flat grids could save.
//!
//! `budget_levels MESH MAP [CELL/LEVELS/BUDGET[/EDGE[/REACH[/RES[/TRACE]]]] ...]`: whole bakes
//! (`Baker::new` and `bake_refined`, as `glint bake` makes them) with the visibility cell size in
//! degrees, the boundary levels, the light budget β, the first level of edge quarters
//! (`CutSettings::edge_quarters_from`, 0: every quarter traced), vertex sampling's reach for
//! taking cells (`RefineSettings::take_reach`, a fraction of the diagonal), the direction set's
//! resolution (per cube-face side) and `CutSettings::trace_leaves` given (`-` or leaving a field
//! out leaves it to the default or the decisions),
//! the default bake first: the rays, the bake's CPU and wall seconds after the decisions, and the
//! visibility error at 400 imported vertices against a ray per direction, weighted by solid angle
//! × cosine × the map's luminance (`tests/it/common.rs`'s `visibility_error`, as the million's is
//! measured).

use glam::{DVec3, Vec3A};
use glint::bake::tracer::Tracer;
use rayon::prelude::*;

#[path = "../tests/it/common.rs"]
mod common;

/// Directions per face side.
const R: usize = 128;
/// The first pass's cells (and blocks), directions a side.
const CELL: usize = 16;
/// Refinement levels: cells of `CELL >> LEVELS` directions a side at the finest.
const LEVELS: usize = 3;

/// A face's axes: (outward axis, u axis, v axis).
fn face(f: usize) -> (DVec3, DVec3, DVec3) {
    let e = [DVec3::X, DVec3::Y, DVec3::Z];
    let sign = if f.is_multiple_of(2) { 1.0 } else { -1.0 };
    (e[f / 2] * sign, e[(f / 2 + 1) % 3], e[(f / 2 + 2) % 3])
}

/// The face coordinate in [−1, 1] of `x` directions from the face's edge.
fn coordinate(x: f64) -> f64 {
    -1.0 + 2.0 * x / R as f64
}

/// The direction at (x, y), in directions from the face's corner, on face `f`.
fn direction(f: usize, x: f64, y: f64) -> DVec3 {
    let (w, u, v) = face(f);
    (w + u * coordinate(x) + v * coordinate(y)).normalize()
}

/// The solid angle of the direction (texel) whose centre is at (x, y).
fn solid_angle(x: f64, y: f64) -> f64 {
    let (a, b) = (coordinate(x), coordinate(y));
    (2.0 / R as f64).powi(2) / (1.0 + a * a + b * b).powf(1.5)
}

/// One probe vertex: its ray origin and normal, and the rays it has cast.
struct Probe<'a> {
    tracer: &'a Tracer,
    origin: Vec3A,
    normal: DVec3,
    rays: u64,
}

impl Probe<'_> {
    fn visible(&mut self, d: DVec3) -> i8 {
        self.rays += 1;
        i8::from(!self.tracer.occluded(self.origin, d.as_vec3().into()))
    }

    /// Whether a block of `s` directions a side at (x0, y0) reaches above the horizon (its corners
    /// and centre).
    fn above(&self, f: usize, x0: usize, y0: usize, s: usize) -> bool {
        let (x0, y0, s) = (x0 as f64, y0 as f64, s as f64);
        [(0.0, 0.0), (s, 0.0), (0.0, s), (s, s), (0.5 * s, 0.5 * s)]
            .iter()
            .any(|&(a, b)| direction(f, x0 + a, y0 + b).dot(self.normal) > 0.0)
    }
}

/// Visibility per direction of face `f` (−1 where nothing was traced) by the quarter scheme, and
/// the rays its first pass cast: [`bisect`] after every level, which leaves nothing to bisect (no
/// segment between two of the finest cells is longer than 1.5 of them), and where each direction's
/// nearest point is its finest cell's centre.
fn quarters(p: &mut Probe, f: usize) -> (Vec<i8>, u64) {
    bisect(p, f, LEVELS)
}

/// Visibility per direction of face `f` by the corner scheme, and the rays its first pass cast.
fn corners(p: &mut Probe, f: usize) -> (Vec<i8>, u64) {
    let start = p.rays;
    let fine = CELL >> LEVELS;
    let side = R / fine + 1;
    let mut points = vec![-1i8; side * side];
    let mut point = |p: &mut Probe, x: usize, y: usize| -> i8 {
        let k = (y / fine) * side + x / fine;
        if points[k] < 0 {
            points[k] = p.visible(direction(f, x as f64, y as f64));
        }
        points[k]
    };
    let mut out = vec![-1i8; R * R];
    let mut blocks: Vec<(usize, usize)> = (0..R / CELL)
        .flat_map(|j| (0..R / CELL).map(move |i| (i * CELL, j * CELL)))
        .filter(|&(x, y)| p.above(f, x, y, CELL))
        .collect();
    let (mut s, mut first) = (CELL, None);
    while !blocks.is_empty() {
        let mut finer = Vec::new();
        for &(x0, y0) in &blocks {
            let c = [
                point(p, x0, y0),
                point(p, x0 + s, y0),
                point(p, x0, y0 + s),
                point(p, x0 + s, y0 + s),
            ];
            if c.iter().all(|&a| a == c[0]) || s == fine {
                for y in y0..y0 + s {
                    for x in x0..x0 + s {
                        let (cx, cy) = (2 * (x - x0) + 1 > s, 2 * (y - y0) + 1 > s);
                        out[y * R + x] = c[2 * usize::from(cy) + usize::from(cx)];
                    }
                }
            } else {
                let h = s / 2;
                finer.extend((0..4).map(|q| (x0 + (q % 2) * h, y0 + (q / 2) * h)));
            }
        }
        first.get_or_insert(p.rays - start);
        blocks = finer;
        s /= 2;
    }
    (out, first.unwrap_or(0))
}

/// Visibility per direction of face `f` by bisection, and the rays its first pass cast: the quarter
/// scheme for `q` levels, then, for each pair of 8-neighbours of unlike visibility among the cells
/// the last of them traced, the segment between their centres bisected (a ray at its midpoint,
/// keeping the half whose ends disagree) until it is no longer than 1.5 finest cells. A direction
/// in a cell of such a pair takes the visibility of the nearest point traced in that cell or its 8
/// neighbours, any other that of the finest cell that holds it.
fn bisect(p: &mut Probe, f: usize, q: usize) -> (Vec<i8>, u64) {
    let start = p.rays;
    let mut out = vec![-1i8; R * R];
    let (mut s, mut m) = (CELL, R / CELL);
    let mut cells = vec![-1i8; m * m];
    for cj in 0..m {
        for ci in 0..m {
            if p.above(f, ci * s, cj * s, s) {
                let c = |i: usize| (i * s) as f64 + 0.5 * s as f64;
                cells[cj * m + ci] = p.visible(direction(f, c(ci), c(cj)));
            }
        }
    }
    let first = p.rays - start;
    let fill = |out: &mut [i8], cells: &[i8], m: usize, s: usize| {
        for (k, &c) in cells.iter().enumerate().filter(|(_, c)| **c >= 0) {
            let (ci, cj) = (k % m, k / m);
            for y in cj * s..(cj + 1) * s {
                out[y * R + ci * s..y * R + (ci + 1) * s].fill(c);
            }
        }
    };
    fill(&mut out, &cells, m, s);
    let unlike = |cells: &[i8], m: usize, ci: i64, cj: i64, c: i8| {
        (-1..=1)
            .flat_map(|dj| (-1..=1).map(move |di| (ci + di, cj + dj)))
            .filter(|&(i, j)| i >= 0 && j >= 0 && i < m as i64 && j < m as i64)
            .any(|(i, j)| {
                let o = cells[j as usize * m + i as usize];
                o >= 0 && o != c
            })
    };
    for _ in 0..q {
        let mut finer = vec![-1i8; 4 * m * m];
        let h = s / 2;
        for (k, &c) in cells.iter().enumerate().filter(|(_, c)| **c >= 0) {
            let (ci, cj) = ((k % m) as i64, (k / m) as i64);
            if unlike(&cells, m, ci, cj, c) {
                for q in 0..4 {
                    let (qi, qj) = (2 * ci as usize + q % 2, 2 * cj as usize + q / 2);
                    let c = |i: usize| (i * h) as f64 + 0.5 * h as f64;
                    finer[qj * 2 * m + qi] = p.visible(direction(f, c(qi), c(qj)));
                }
            }
        }
        (s, m) = (h, 2 * m);
        fill(&mut out, &finer, m, s);
        cells = finer;
    }
    let fine = (CELL >> LEVELS) as f64;
    let centre = |i: usize| (i * s) as f64 + 0.5 * s as f64;
    let mut buckets: Vec<Vec<(f64, f64, i8)>> = vec![Vec::new(); m * m];
    let mut edge = vec![false; m * m];
    for (k, &c) in cells.iter().enumerate().filter(|(_, c)| **c >= 0) {
        buckets[k].push((centre(k % m), centre(k / m), c));
    }
    let bucket = |x: f64, y: f64| {
        let i = ((x / s as f64) as usize).min(m - 1);
        let j = ((y / s as f64) as usize).min(m - 1);
        j * m + i
    };
    for cj in 0..m {
        for ci in 0..m {
            let a = cells[cj * m + ci];
            if a < 0 {
                continue;
            }
            for (di, dj) in [(1i64, 0i64), (-1, 1), (0, 1), (1, 1)] {
                let (i, j) = (ci as i64 + di, cj as i64 + dj);
                if i < 0 || i >= m as i64 || j < 0 || j >= m as i64 {
                    continue;
                }
                let b = cells[j as usize * m + i as usize];
                if b < 0 || b == a {
                    continue;
                }
                edge[cj * m + ci] = true;
                edge[j as usize * m + i as usize] = true;
                let (mut lo, mut hi) = (
                    (centre(ci), centre(cj)),
                    (centre(i as usize), centre(j as usize)),
                );
                while (hi.0 - lo.0).hypot(hi.1 - lo.1) > fine * 1.5 {
                    let mid = (0.5 * (lo.0 + hi.0), 0.5 * (lo.1 + hi.1));
                    let v = p.visible(direction(f, mid.0, mid.1));
                    buckets[bucket(mid.0, mid.1)].push((mid.0, mid.1, v));
                    if v == a {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
            }
        }
    }
    for y in 0..R {
        for x in 0..R {
            let (bi, bj) = ((x / s) as i64, (y / s) as i64);
            if !edge[bj as usize * m + bi as usize] {
                continue;
            }
            let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
            let mut best = (f64::INFINITY, -1i8);
            for j in (bj - 1).max(0)..=(bj + 1).min(m as i64 - 1) {
                for i in (bi - 1).max(0)..=(bi + 1).min(m as i64 - 1) {
                    for &(qx, qy, v) in &buckets[j as usize * m + i as usize] {
                        let d = (qx - px).powi(2) + (qy - py).powi(2);
                        if d < best.0 {
                            best = (d, v);
                        }
                    }
                }
            }
            out[y * R + x] = best.1;
        }
    }
    (out, first)
}

/// A scheme: visibility per direction of a face, and the rays its first pass cast.
type Scheme = fn(&mut Probe, usize) -> (Vec<i8>, u64);

/// The schemes `edge_schemes` compares, by the name it prints.
const SCHEMES: [(&str, Scheme); 5] = [
    ("quarters", quarters),
    ("corners", corners),
    ("bisect after 0 levels", |p, f| bisect(p, f, 0)),
    ("bisect after 1 level", |p, f| bisect(p, f, 1)),
    ("bisect after 2 levels", |p, f| bisect(p, f, 2)),
];

/// Per scheme: rays, first-pass rays, Σ |error| weighted by geometry and by luminance.
#[derive(Default, Clone, Copy)]
struct Tally {
    rays: f64,
    first: f64,
    geometry: f64,
    light: f64,
}

fn edge_schemes(mesh: &str, map: &str, probes: usize) -> anyhow::Result<()> {
    let scene = glint::scene::import(&common::assets().join(format!("glb/{mesh}.glb")))?;
    let env = glint::env::load(&common::assets().join(format!("hdr/{map}.exr")))?;
    let mesh = &scene.mesh;
    let tracer = Tracer::new(mesh);
    let offset = 1e-4 * f64::from(scene.bounds.diagonal().max(1e-12));
    // Per direction of each face: solid angle, and solid angle × luminance (the mean of RGB).
    let weights: Vec<Vec<(f64, f64)>> = (0..6)
        .map(|f| {
            (0..R * R)
                .map(|k| {
                    let (x, y) = ((k % R) as f64 + 0.5, (k / R) as f64 + 0.5);
                    let rgb = env.lookup(direction(f, x, y), 0.0);
                    let omega = solid_angle(x, y);
                    (omega, omega * (rgb[0] + rgb[1] + rgb[2]) / 3.0)
                })
                .collect()
        })
        .collect();
    let n = mesh.positions.len();
    let per_probe: Vec<([Tally; SCHEMES.len()], (f64, f64))> = (0..probes)
        .into_par_iter()
        .map(|i| {
            let v = (2 * i + 1) * n / (2 * probes);
            let normal = mesh.normals[v].as_dvec3().normalize();
            let origin = mesh.positions[v].as_dvec3() + normal * offset;
            let mut p = Probe {
                tracer: &tracer,
                origin: origin.as_vec3().into(),
                normal,
                rays: 0,
            };
            let mut t = [Tally::default(); SCHEMES.len()];
            let mut total = (0.0, 0.0);
            for (f, weights) in weights.iter().enumerate() {
                let mut results = Vec::new();
                for (s, (_, scheme)) in SCHEMES.iter().enumerate() {
                    let before = p.rays;
                    let (vis, first) = scheme(&mut p, f);
                    t[s].rays += (p.rays - before) as f64;
                    t[s].first += first as f64;
                    results.push(vis);
                }
                for k in 0..R * R {
                    let d = direction(f, (k % R) as f64 + 0.5, (k / R) as f64 + 0.5);
                    let cos = d.dot(normal);
                    if cos <= 0.0 {
                        continue;
                    }
                    let truth = p.visible(d);
                    let (g, l) = (weights[k].0 * cos, weights[k].1 * cos);
                    total = (total.0 + g, total.1 + l);
                    for (s, vis) in results.iter().enumerate() {
                        if vis[k] != truth {
                            t[s].geometry += g;
                            t[s].light += l;
                        }
                    }
                }
            }
            (t, total)
        })
        .collect();
    println!(
        "{} probes, {R} directions a side, cells of {CELL} a side refined {LEVELS} times",
        probes
    );
    println!(
        "| scheme | rays per vertex | of them the first pass | error, solid angle × cosine | error, × luminance |"
    );
    println!("|---|---|---|---|---|");
    // Pooled over the probes: Σ |error| weight / Σ weight, as the million's error is measured.
    let total = per_probe
        .iter()
        .fold((0.0, 0.0), |a, (_, w)| (a.0 + w.0, a.1 + w.1));
    for (s, (name, _)) in SCHEMES.iter().enumerate() {
        let sum = per_probe.iter().fold(Tally::default(), |a, (t, _)| Tally {
            rays: a.rays + t[s].rays,
            first: a.first + t[s].first,
            geometry: a.geometry + t[s].geometry,
            light: a.light + t[s].light,
        });
        println!(
            "| {name} | {:.0} | {:.0} | {:.3} % | {:.3} % |",
            sum.rays / probes as f64,
            sum.first / probes as f64,
            100.0 * sum.geometry / total.0,
            100.0 * sum.light / total.1
        );
    }
    Ok(())
}

/// Cell sizes (directions a side) of `flat_cells`' levels: the first pass's and each refinement's.
const FLAT_SIZES: [usize; LEVELS + 1] = [CELL, CELL / 2, CELL / 4, CELL / 8];

/// Per level and face, what a cell of that level needs, independent of the vertex: its ray
/// direction (its centre), its four corners' directions (the horizon test), Σ Ω d over its
/// directions (its cosine mass is that · n where it lies above the horizon) and Σ r Ω d (the light
/// it gates, r the rotation-worst luminance at its elevation).
struct FlatCells {
    centre: Vec<Vec3A>,
    corners: Vec<[DVec3; 4]>,
    moment: Vec<DVec3>,
    light: Vec<DVec3>,
    omega: Vec<f64>,
}

fn flat_tables(ring: &dyn Fn(f64) -> f64) -> Vec<[FlatCells; 6]> {
    FLAT_SIZES
        .iter()
        .map(|&s| {
            let m = R / s;
            std::array::from_fn(|f| {
                let mut t = FlatCells {
                    centre: Vec::with_capacity(m * m),
                    corners: Vec::with_capacity(m * m),
                    moment: Vec::with_capacity(m * m),
                    light: Vec::with_capacity(m * m),
                    omega: Vec::with_capacity(m * m),
                };
                for j in 0..m {
                    for i in 0..m {
                        let (x0, y0) = ((i * s) as f64, (j * s) as f64);
                        let c = direction(f, x0 + 0.5 * s as f64, y0 + 0.5 * s as f64);
                        t.centre.push(c.as_vec3().into());
                        let sf = s as f64;
                        t.corners.push([
                            direction(f, x0, y0),
                            direction(f, x0 + sf, y0),
                            direction(f, x0, y0 + sf),
                            direction(f, x0 + sf, y0 + sf),
                        ]);
                        let (mut mo, mut li, mut om) = (DVec3::ZERO, DVec3::ZERO, 0.0);
                        for y in j * s..(j + 1) * s {
                            for x in i * s..(i + 1) * s {
                                let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                                let d = direction(f, px, py);
                                let w = solid_angle(px, py);
                                mo += d * w;
                                li += d * w * ring(d.y);
                                om += w;
                            }
                        }
                        t.moment.push(mo);
                        t.light.push(li);
                        t.omega.push(om);
                    }
                }
                t
            })
        })
        .collect()
}

/// One probe's state in `flat_cells`: per level and face, each cell's visibility (−1 unknown) and
/// whether it was refined, and the rays, recorded or replayed.
struct Flat<'a> {
    tables: &'a [[FlatCells; 6]],
    n: DVec3,
    vis: Vec<[Vec<i8>; 6]>,
    refined: Vec<[Vec<bool>; 6]>,
    /// Per traced cell of the level, its neighbours of the other visibility (bit j for the j-th of
    /// [`NEIGHBOURS`]).
    masks: [Vec<u8>; 6],
}

/// The 8-neighbourhood, in the order of the bits of [`Flat::masks`].
const NEIGHBOURS: [(i64, i64); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];

impl Flat<'_> {
    fn above(&self, l: usize, f: usize, k: usize) -> bool {
        self.tables[l][f].corners[k]
            .iter()
            .any(|d| d.dot(self.n) > 0.0)
    }
}

/// The flat pipeline for one probe: the first pass, `LEVELS` levels of marking (a traced cell with
/// an 8-neighbour of the other visibility, on its own face), the light budget β over the vertex's
/// hemisphere total, edge quarters (the quarters beside a neighbour of the other visibility; at the
/// first level the others too where one of them disagrees with its cell), then the cut: the
/// quadtree of each face merged bottom-up while Σ Ω c |V − V̄| ≤ ε Ω. `trace` answers a batch of
/// directions (occluded or not). Returns the cut's entry count.
fn flat_probe(
    st: &mut Flat,
    beta: f64,
    total: f64,
    trace: &mut dyn FnMut(&[Vec3A], &mut Vec<bool>),
) -> usize {
    let n = st.n;
    let mut dirs = Vec::new();
    let mut keys: Vec<(usize, usize)> = Vec::new();
    let mut answers = Vec::new();
    for l in 0..=LEVELS {
        for f in 0..6 {
            st.vis[l][f].fill(-1);
            st.refined[l][f].fill(false);
        }
    }
    // The first pass.
    let m0 = R / FLAT_SIZES[0];
    for f in 0..6 {
        for k in 0..m0 * m0 {
            if st.above(0, f, k) {
                dirs.push(st.tables[0][f].centre[k]);
                keys.push((f, k));
            }
        }
    }
    trace(&dirs, &mut answers);
    for (&(f, k), &o) in keys.iter().zip(&answers) {
        st.vis[0][f][k] = i8::from(!o);
    }
    // The cells traced at the current level: the ones the marking looks at.
    let mut traced = keys.clone();
    for (l, &size) in FLAT_SIZES.iter().enumerate().take(LEVELS) {
        let m = R / size;
        // Marking.
        let mut marked: Vec<(f64, usize, usize)> = Vec::new();
        for f in 0..6 {
            let masks = &mut st.masks[f];
            masks.clear();
            masks.resize(m * m, 0);
        }
        {
            for &(f, k) in &traced {
                let vis = &st.vis[l][f];
                let masks = &mut st.masks[f];
                let v = vis[k];
                let (i, j) = ((k % m) as i64, (k / m) as i64);
                let mut mask = 0u8;
                for (b, &(di, dj)) in NEIGHBOURS.iter().enumerate() {
                    let (a, c) = (i + di, j + dj);
                    if a < 0 || c < 0 || a >= m as i64 || c >= m as i64 {
                        continue;
                    }
                    let o = vis[(c as usize) * m + a as usize];
                    if o >= 0 && o != v {
                        mask |= 1 << b;
                    }
                }
                masks[k] = mask;
                if mask != 0 {
                    let g = st.tables[l][f].light[k].dot(n).max(0.0);
                    marked.push((g, f, k));
                }
            }
        }
        // The light budget: the marked cells gating the least light stay coarse.
        marked.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        let (mut spent, budget) = (0.0, beta * total);
        let mut start = 0;
        while start < marked.len() && spent + marked[start].0 <= budget {
            spent += marked[start].0;
            start += 1;
        }
        if start == marked.len() {
            break;
        }
        // Edge quarters.
        let q = 2 * m;
        for f in 0..6 {
            st.vis[l + 1][f].fill(-1);
        }
        dirs.clear();
        keys.clear();
        let mut held: Vec<(usize, usize, usize)> = Vec::new();
        for &(_, f, k) in &marked[start..] {
            st.refined[l][f][k] = true;
            let (i, j) = (k % m, k / m);
            let mask = st.masks[f][k];
            for (qi, qj) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let qk = (2 * j + qj) * q + 2 * i + qi;
                if !st.above(l + 1, f, qk) {
                    continue;
                }
                // The parent's neighbours this quarter borders.
                let (dx, dy) = (2 * qi as i64 - 1, 2 * qj as i64 - 1);
                let near = NEIGHBOURS.iter().enumerate().any(|(b, &(di, dj))| {
                    mask >> b & 1 == 1 && (di == 0 || di == dx) && (dj == 0 || dj == dy)
                });
                if near {
                    dirs.push(st.tables[l + 1][f].centre[qk]);
                    keys.push((f, qk));
                } else {
                    st.vis[l + 1][f][qk] = st.vis[l][f][k];
                    if l == 0 {
                        held.push((f, k, qk));
                    }
                }
            }
        }
        trace(&dirs, &mut answers);
        for (&(f, qk), &o) in keys.iter().zip(&answers) {
            st.vis[l + 1][f][qk] = i8::from(!o);
        }
        traced.clear();
        traced.extend_from_slice(&keys);
        if l == 0 && !held.is_empty() {
            // The first level's other quarters, where an edge quarter disagrees with its cell.
            let crossed = |f: usize, k: usize, st: &Flat| {
                let (i, j) = (k % m, k / m);
                [(0, 0), (1, 0), (0, 1), (1, 1)].iter().any(|&(qi, qj)| {
                    let v = st.vis[1][f][(2 * j + qj) * q + 2 * i + qi];
                    v >= 0 && v != st.vis[0][f][k]
                })
            };
            dirs.clear();
            keys.clear();
            for &(f, k, qk) in &held {
                if crossed(f, k, st) {
                    dirs.push(st.tables[1][f].centre[qk]);
                    keys.push((f, qk));
                }
            }
            trace(&dirs, &mut answers);
            for (&(f, qk), &o) in keys.iter().zip(&answers) {
                st.vis[1][f][qk] = i8::from(!o);
            }
            traced.extend_from_slice(&keys);
        }
    }
    // The cut, face by face: the quadtree from the face down to the finest cells known.
    let mut entries = 0;
    for f in 0..6 {
        entries += flat_merge(st, f, 0, 0, R, 0.02)[3] as usize;
    }
    entries
}

/// (Σ Ω c, Σ Ω c V, error bound, entries, solid angle) of the quadtree node at (x, y) of `s`
/// directions a side on face `f`, merged where its four children are single entries within ε.
fn flat_merge(st: &Flat, f: usize, x: usize, y: usize, s: usize, eps: f64) -> [f64; 5] {
    let n = st.n;
    if let Some(l) = FLAT_SIZES.iter().position(|&c| c == s) {
        let m = R / s;
        let k = (y / s) * m + x / s;
        let v = st.vis[l][f][k];
        if l == LEVELS || !st.refined[l][f][k] {
            let omega = st.tables[l][f].omega[k];
            if v < 0 {
                return [0.0, 0.0, 0.0, 0.0, omega];
            }
            let w = st.tables[l][f].moment[k].dot(n).max(0.0);
            if w <= 0.0 {
                return [0.0, 0.0, 0.0, 0.0, omega];
            }
            return [w, w * f64::from(v), 0.0, 1.0, omega];
        }
    }
    let h = s / 2;
    let mut kids = [[0.0; 5]; 4];
    for (c, (dx, dy)) in [(0, 0), (h, 0), (0, h), (h, h)].into_iter().enumerate() {
        kids[c] = flat_merge(st, f, x + dx, y + dy, h, eps);
    }
    let sum = |i: usize| kids.iter().map(|k| k[i]).sum::<f64>();
    let (w, wv, e, omega) = (sum(0), sum(1), sum(3), sum(4));
    if w <= 0.0 {
        return [0.0, 0.0, 0.0, 0.0, omega];
    }
    let vp = wv / w;
    let dev: f64 = kids.iter().map(|k| k[2] + (k[1] - k[0] * vp).abs()).sum();
    let single = kids.iter().all(|k| k[3] <= 1.0);
    let e = if single && dev <= eps * omega { 1.0 } else { e };
    [w, wv, dev, e, omega]
}

/// Each direction's visibility on face `f`: its finest known cell's.
fn flat_texels(st: &Flat, f: usize) -> Vec<i8> {
    let mut out = vec![-1i8; R * R];
    for (l, &s) in FLAT_SIZES.iter().enumerate() {
        let m = R / s;
        for (k, &v) in st.vis[l][f].iter().enumerate() {
            if v < 0 {
                continue;
            }
            let (i, j) = (k % m, k / m);
            for y in j * s..(j + 1) * s {
                out[y * R + i * s..y * R + (i + 1) * s].fill(v);
            }
        }
    }
    out
}

fn flat_cells(mesh: &str, map: &str) -> anyhow::Result<()> {
    use glint::bake::{BakeSettings, Baker};
    let scene = glint::scene::import(&common::assets().join(format!("glb/{mesh}.glb")))?;
    let env = glint::env::load(&common::assets().join(format!("hdr/{map}.exr")))?;
    // The bake at the flat grid's resolution, so that both cut the same directions.
    let settings = BakeSettings {
        resolution: Some(R),
        ..BakeSettings::default()
    };
    let baker = Baker::new(&scene, &env, settings)?;
    if baker.decisions.cell_deg != 11.25 || baker.decisions.boundary_levels != LEVELS as u32 {
        anyhow::bail!(
            "{mesh} under {map} decides {}° cells and {} levels; flat_cells compares 11.25° and {LEVELS}",
            baker.decisions.cell_deg,
            baker.decisions.boundary_levels
        );
    }
    let mut baker = baker;
    // Each vertex on its own, as the flat pipeline traces them: the 400 are far apart, so grouping
    // them (as the bake groups neighbours) would only make Embree's streams incoherent.
    baker.group_points = false;
    let baker = baker;
    let beta = baker.settings.cut.boundary_budget;
    // The rotation-worst luminance per elevation (rotations about +Y), in 512 bins of d.y.
    const BINS: usize = 512;
    let mut ring = vec![0.0f64; BINS];
    let bin = |y: f64| (((y + 1.0) * 0.5 * BINS as f64) as usize).min(BINS - 1);
    for f in 0..6 {
        for k in 0..R * R {
            let d = direction(f, (k % R) as f64 + 0.5, (k / R) as f64 + 0.5);
            let rgb = env.lookup(d, 0.0);
            let b = bin(d.y);
            ring[b] = ring[b].max((rgb[0] + rgb[1] + rgb[2]) / 3.0);
        }
    }
    let ring_at = |y: f64| ring[bin(y)];
    let tables = flat_tables(&ring_at);
    let vertices = common::error_sample(scene.mesh.positions.len());
    let points: Vec<(DVec3, DVec3)> = vertices
        .iter()
        .map(|&v| {
            let (o, n) = baker
                .ray_origin(v as usize)
                .ok_or_else(|| anyhow::anyhow!("vertex {v} has no ray origin"))?;
            Ok((o - n * baker.ray_offset(), n))
        })
        .collect::<anyhow::Result<_>>()?;
    // The bake's own cuts of the same points, one thread, three times (the last one's kept).
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let mut bake_times = Vec::new();
    let mut cut = || {
        let t = std::time::Instant::now();
        let bake = pool.install(|| baker.point_cuts(&points));
        bake_times.push(t.elapsed().as_secs_f64());
        bake
    };
    cut();
    cut();
    let (cuts, bake_rays) = cut();
    let luminance = common::leaf_luminance(&env, &baker);
    let (mut wrong, mut total) = (0.0, 0.0);
    let mut bake_entries = 0usize;
    for (i, &v) in vertices.iter().enumerate() {
        let cut: Vec<(u32, f32)> = cuts.cut(i).collect();
        bake_entries += cut.len();
        let (e, w) = common::visibility_error(&baker, &luminance, v, &cut);
        wrong += e;
        total += w;
    }
    // The flat pipeline, one thread, three times (rays timed apart).
    let tracer = &baker.tracer;
    let mut st = Flat {
        tables: &tables,
        n: DVec3::Y,
        vis: FLAT_SIZES
            .iter()
            .map(|&s| std::array::from_fn(|_| vec![-1i8; (R / s) * (R / s)]))
            .collect(),
        refined: FLAT_SIZES
            .iter()
            .map(|&s| std::array::from_fn(|_| vec![false; (R / s) * (R / s)]))
            .collect(),
        masks: std::array::from_fn(|_| Vec::new()),
    };
    let mut flat_times = Vec::new();
    let mut ray_times = Vec::new();
    let (mut flat_rays, mut flat_entries, mut fwrong, mut ftotal) = (0u64, 0usize, 0.0, 0.0);
    for run in 0..3 {
        let (mut all, mut rays_s) = (0.0, 0.0);
        for &(p, n) in &points {
            st.n = n;
            let origin: Vec3A = (p + n * baker.ray_offset()).as_vec3().into();
            let total_light: f64 = (0..6)
                .map(|f| {
                    tables[LEVELS][f]
                        .light
                        .iter()
                        .map(|l| l.dot(n).max(0.0))
                        .sum::<f64>()
                })
                .sum();
            let t = std::time::Instant::now();
            let mut rays = 0u64;
            let entries = flat_probe(&mut st, beta, total_light, &mut |dirs, out| {
                let r = std::time::Instant::now();
                out.clear();
                out.resize(dirs.len(), false);
                tracer.occluded_from(origin, dirs, out);
                rays += dirs.len() as u64;
                rays_s += r.elapsed().as_secs_f64();
            });
            all += t.elapsed().as_secs_f64();
            if run == 0 {
                flat_rays += rays;
                flat_entries += entries;
                for f in 0..6 {
                    for (k, &got) in flat_texels(&st, f).iter().enumerate() {
                        let (x, y) = ((k % R) as f64 + 0.5, (k / R) as f64 + 0.5);
                        let d = direction(f, x, y);
                        let cos = d.dot(n);
                        if cos <= 0.0 {
                            continue;
                        }
                        let rgb = env.lookup(d, 0.0);
                        let w = solid_angle(x, y) * cos * (rgb[0] + rgb[1] + rgb[2]) / 3.0;
                        let truth = i8::from(!tracer.occluded(origin, d.as_vec3().into()));
                        if got != truth {
                            fwrong += w;
                        }
                        ftotal += w;
                    }
                }
            }
        }
        flat_times.push(all);
        ray_times.push(rays_s);
    }
    let med = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let np = points.len() as f64;
    println!(
        "{} vertices of {mesh} under {map}, one thread, median of 3; {} directions a side, cells of {CELL} a side, {LEVELS} levels, β {beta}",
        points.len(),
        baker.set.resolution()
    );
    println!(
        "| cuts | rays per vertex | µs per vertex | of them in the tracer | cut entries per vertex | error, × luminance |"
    );
    println!("|---|---|---|---|---|---|");
    println!(
        "| the bake's (`Baker::point_cuts`) | {:.0} | {:.0} | | {:.0} | {:.3} % |",
        bake_rays as f64 / np,
        1e6 * med(&mut bake_times) / np,
        bake_entries as f64 / np,
        100.0 * wrong / total
    );
    println!(
        "| flat, per face | {:.0} | {:.0} | {:.0} | {:.0} | {:.3} % |",
        flat_rays as f64 / np,
        1e6 * med(&mut flat_times) / np,
        1e6 * med(&mut ray_times) / np,
        flat_entries as f64 / np,
        100.0 * fwrong / ftotal
    );
    Ok(())
}

/// CPU seconds of this process so far (user and system).
fn cpu_seconds() -> f64 {
    // SAFETY: getrusage writes the struct it is given; a zeroed rusage is a valid value.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: RUSAGE_SELF with a valid pointer to that struct.
    unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) };
    let t = |x: libc::timeval| x.tv_sec as f64 + x.tv_usec as f64 * 1e-6;
    t(u.ru_utime) + t(u.ru_stime)
}

fn budget_levels(mesh: &str, map: &str, variants: &[&str]) -> anyhow::Result<()> {
    use glint::bake::{BakeSettings, Baker};
    let scene = glint::scene::import(&common::assets().join(format!("glb/{mesh}.glb")))?;
    let env = glint::env::load(&common::assets().join(format!("hdr/{map}.exr")))?;
    println!(
        "| cell, levels, β, edge quarters asked | decided cell, levels | directions a side | rays | baked vertices | bake CPU (s) | bake wall (s) | error at 400 vertices |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for variant in std::iter::once("-/-/-").chain(variants.iter().copied()) {
        let parts: Vec<&str> = variant.split('/').collect();
        if !(3..=7).contains(&parts.len()) {
            anyhow::bail!(
                "{variant}: expected CELL/LEVELS/BUDGET[/EDGE[/REACH[/RES[/TRACE]]]], each a number or -"
            );
        }
        let field = |i: usize| parts.get(i).copied().unwrap_or("-");
        let (cell, levels, budget, edge, reach, res, trace) = (
            field(0),
            field(1),
            field(2),
            field(3),
            field(4),
            field(5),
            field(6),
        );
        let mut settings = BakeSettings::default();
        if cell != "-" {
            settings.cell_deg = Some(cell.parse()?);
        }
        if levels != "-" {
            settings.boundary_levels = Some(levels.parse()?);
        }
        if budget != "-" {
            settings.cut.boundary_budget = budget.parse()?;
        }
        if edge != "-" {
            settings.cut.edge_quarters_from = edge.parse()?;
        }
        if reach != "-" {
            settings.refine.take_reach = reach.parse()?;
        }
        if res != "-" {
            settings.resolution = Some(res.parse()?);
        }
        if trace != "-" {
            settings.cut.trace_leaves = trace.parse()?;
        }
        let baker = Baker::new(&scene, &env, settings)?;
        let (c0, t0) = (cpu_seconds(), std::time::Instant::now());
        let bake = baker.bake_refined(None, &|_| {});
        let (cpu, wall) = (cpu_seconds() - c0, t0.elapsed().as_secs_f64());
        let luminance = common::leaf_luminance(&env, &baker);
        let (mut wrong, mut total) = (0.0, 0.0);
        for v in common::error_sample(scene.mesh.positions.len()) {
            let cut: Vec<(u32, f32)> = bake.cuts.cut(v as usize).collect();
            let (e, w) = common::visibility_error(&baker, &luminance, v, &cut);
            wrong += e;
            total += w;
        }
        println!(
            "| {variant} | {}°, {} | {} | {:.1} M | {} | {cpu:.2} | {wall:.2} | {:.3} % |",
            baker.decisions.cell_deg,
            baker.decisions.boundary_levels,
            baker.set.resolution(),
            bake.stats.rays_traced as f64 * 1e-6,
            bake.stats.vertices,
            100.0 * wrong / total
        );
    }
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.iter().map(String::as_str).collect::<Vec<_>>()[..] {
        ["edge_schemes", mesh, map] => edge_schemes(mesh, map, 400),
        ["edge_schemes", mesh, map, probes] => edge_schemes(mesh, map, probes.parse()?),
        ["budget_levels", mesh, map, ref variants @ ..] => budget_levels(mesh, map, variants),
        ["flat_cells", mesh, map] => flat_cells(mesh, map),
        _ => anyhow::bail!(
            "usage: bake_studies edge_schemes MESH MAP [PROBES] | budget_levels MESH MAP [CELL/LEVELS/BUDGET[/EDGE[/REACH[/RES[/TRACE]]]] ...] | flat_cells MESH MAP"
        ),
    }
}
