//! Per-vertex visibility cuts through the light tree (method.md §4; Åkerlund et al. 2007).
//!
//! Inputs: a vertex (position, unit normal), the [`LightTree`], a [`Tracer`] and [`CutSettings`].
//! Output: the vertex's cut — tree nodes that partition the leaves above its horizon — with, per
//! node, the cosine-weighted visible fraction
//!   V_k = Σ_{i∈k} Ω_i c_i V_i / Σ_{i∈k} Ω_i c_i,   c_i = max(d_i·n, 0),  V_i ∈ {0, 1}
//! (V_i = visibility of leaf direction d_i by a ray from the vertex offset along n; with visibility
//! cells of C > 1 leaves, V_i is the visibility along the mean direction of the cell that holds
//! leaf i). The mean of Ṽ = V·max(cos, 0) over a node follows exactly: ⟨Ṽ⟩_k = V_k · Σ Ω_i c_i /
//! Ω_k; and within the node Ṽ is reconstructed as V_k·c_i, which is exact when V is constant over
//! the node.
//!
//! Algorithm (top-down, then merged bottom-up):
//! 1. A node wholly below the horizon is dropped (Ṽ = 0, no rays).
//! 2. A node whose cone of directions is free ([`Tracer::cone_free`]) is visible, V = 1, exactly,
//!    with no rays: this settles open sky wholesale. Tested above the nodes of rule 4, and inside
//!    them on nodes of more than [`CutSettings::cone_leaves`] leaves where that is set. At the
//!    root, an imported vertex takes decision (a)'s test of its hemisphere ([`Prior::root_hemisphere`]).
//! 3. A node so near the horizon that ½·Σ Ω_i c_i ≤ ε·Ω_k is accepted with V = ½ and no rays:
//!    whatever its true visibility, the mean |Ṽ| error over it is within ε.
//! 4. Otherwise a node with at most `trace_leaves` leaves has every above-horizon leaf traced;
//!    larger nodes are split.
//! 5. Sibling results merge into their parent while the error bound Σ_i Ω_i c_i |V_i − V_parent| ≤
//!    ε·Ω_parent holds, i.e. the mean absolute error of Ṽ over the node is at most ε (the bound is
//!    exact for traced leaves and conservative above them).
//! 6. Boundary refinement (`boundary_levels` > 0, decided with the cell size): a traced cell with a
//!    traced neighbour of the other visibility ([`CellNeighbours`], the cube map's 8-neighbourhood)
//!    has a shadow edge through or beside it; it is traced again as cells of a quarter of its
//!    leaves (half as wide) and the cut rebuilt, up to `boundary_levels` times. A ray per cell
//!    moves a shadow edge to the cells' borders; this puts it within the finer cells where it
//!    matters, and leaves open sky and solid occluders at the coarse size (teapot under a uniform
//!    sky, 5.625° cells: the error against a ray per direction 0.0229 → 0.0002 sr with two levels,
//!    at 19 % of that bake's rays). Under a light budget β ([`CutSettings::boundary_budget`],
//!    [`LightGate`]) a level's marked cells that gate the least light are left coarse while their
//!    light sums to at most β of the vertex's: the rays go to the shadow edges of the lights, not
//!    to those across parts of the map that are dark under every rotation (dragon_100k under
//!    studio_1k, 11.25° cells refined three times: 109 M → 34 M rays, the irradiance 0.18–1.26 % →
//!    0.27–1.29 % of a ray per direction's over four rotations). The levels are traced one after
//!    the other, each marking among the cells the level before traced, with no cut built between
//!    them; after the last, the cut is rebuilt once, only in the subtrees that hold a cell the
//!    first level marked (every finer cell lies within one), and the rest is taken from the first
//!    pass (memos per node of at least a cell's size; the same cut as rebuilding it whole after
//!    every level, [`CutSettings::rebuild_whole_passes`], tested). A level's rays go in packets:
//!    the quarters of its marked cells, in leaf order. Only the quarters beside a cell of the
//!    other visibility are traced ([`CutSettings::edge_quarters_from`]: the side of the edge that
//!    marked the cell); the others take the cell's visibility (where every quarter is traced,
//!    about 89 % of them find their cell's visibility again: docs/benchmarks.md). At the first
//!    level, where cells are widest, a cell's other quarters are traced after all where one of
//!    its edge quarters disagrees with it ([`CutSettings::far_quarters_through`]: the edge
//!    crosses into it and may bend).
//! 7. If the cut has more than `max_cut` nodes, ε is doubled and the merge redone (traced cells are
//!    cached, so no ray is cast twice) until it fits; such vertices are counted. Only the merge (5)
//!    takes the relaxed ε; the blind guess (3) keeps the settings' ε.
//!
//! 8. A vertex may be given its neighbours' agreed cells ([`Prior`], [`super::sparse`] rules 4
//!    and 5): those cells are set before the cut is built and cast no ray. A node above the cell
//!    size whose cells are all given is not cone-tested, nor one with a cell given as occluded (its
//!    cone is not free); where they are all given alike and the node lies wholly above the
//!    horizon, it enters the cut as it stands (what merging its cells gives). Everything else is
//!    as above.
//! 9. Vertices may be cut in groups ([`plan_first_pass`], [`GroupRays`]; [`crate::bake::Baker`]
//!    groups 16 neighbours): each one's first pass is planned before it is traced — the descent
//!    of rules 1–4 with its cone tests, down to the nodes whose cells it traces, collecting their
//!    rays — and the group's rays go to the tracer in one call (one stream where Embree traces,
//!    [`Tracer::occluded_grouped`]); each cut
//!    then takes them as traced. What the first pass traces and tests depends on no ray's answer,
//!    so the cut is the same as cutting the vertex alone. Where boundary refinement follows, a
//!    planned vertex's first-pass cut is not built at all: the marking reads only the cells'
//!    answers, and the pass after the levels is built whole (the cut the memos of rule 6 give;
//!    built as the first pass where no cell is marked).
//!
//! Invariants: the cut's nodes are disjoint and in pre-order (= leaf order); every above-horizon
//! leaf lies in exactly one; values are in [0, 1]; the result does not depend on the thread that
//! made it.

use super::tracer::Tracer;
use crate::sphere::{DirectionSet, LightTree};
use glam::{DVec3, Vec3A};
use serde::{Deserialize, Serialize};

/// Knobs of the cut.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CutSettings {
    /// Error bound ε on the mean |Ṽ error| over any cut node.
    pub epsilon: f64,
    /// Cap on the number of nodes in one vertex's cut.
    pub max_cut: usize,
    /// Nodes with at most this many leaves are ray traced cell by cell when their cone is not free
    /// (0, the default: half the tree's leaves, whatever the resolution). Then the cone test is
    /// made on the root (a vertex's whole upper hemisphere) and not on the quarter- and
    /// eighth-spheres below it, whose tests cost more than the rays they save on a detailed mesh
    /// (release build, `glint bake --json`, 64 directions a side: dragon_100k under courtyard 5.5 %
    /// faster than with 4096, with 4.5 % more rays; the bunny and the teapot under studio 1 %
    /// slower; at 128 a side, dragon_100k under interior_1k 7 % less CPU than with 12288, with
    /// 1.6 % more rays: docs/benchmarks.md).
    pub trace_leaves: usize,
    /// Visibility resolution: nodes with at most this many leaves are visibility cells, traced with
    /// one ray along their mean direction (1 = every leaf direction is traced). Light and BRDF
    /// still use every leaf; within a cell Ṽ = V_cell·max(cos, 0).
    pub cell_leaves: usize,
    /// Ray origin offset along the normal, as a fraction of the bounding-box diagonal.
    pub ray_offset: f64,
    /// Boundary refinement: a 2×2 block of visibility cells whose rays disagree (a shadow edge
    /// crosses it) is traced again with cells half as wide, up to this many times (0: off).
    /// Point-sampled cells alias at shadow edges; this resolves the edges at the finer size and
    /// leaves open sky and solid occluders at the coarse one. [`crate::bake::Baker`] sets it from
    /// decision (d).
    #[serde(default)]
    pub boundary_levels: u32,
    /// Inside the nodes traced cell by cell (`trace_leaves`), nodes of more than this many leaves
    /// are still cone-tested ([`Tracer::cone_free`]), and a free one is visible without rays; the
    /// cells of the others are traced in packets per node of at most this many leaves (0: off,
    /// the whole node's cells in one batch). The cut is the same either way (a free cone holds
    /// no geometry, so each of its cells' rays would find V = 1): it pays where cells are single
    /// directions, as in decision (d)'s reference, a ray per direction (the bunny under
    /// interior_1k, 128 directions a side: see docs/benchmarks.md).
    #[serde(default)]
    pub cone_leaves: usize,
    /// Boundary refinement spends its rays where the light is: per level, the marked cells that
    /// gate the least light are left at their size while the light they gate sums to at most this
    /// fraction of the vertex's hemisphere total ([`LightGate`]; 0: every marked cell is refined,
    /// as without a gate).
    #[serde(default)]
    pub boundary_budget: f64,
    /// Boundary refinement rebuilds the whole cut after every level (the build traces the next
    /// level's cells as it meets them), instead of tracing the levels one after the other and
    /// rebuilding once, only the subtrees where the first level marked cells (the rest taken from
    /// the first pass, [`CutScratch`]'s memos). The cut is the same either way: off by default;
    /// on, it is the reference the direct levels and the memos are tested against.
    #[serde(default)]
    pub rebuild_whole_passes: bool,
    /// From this boundary level on (1 = the first; 0: never), a marked cell is traced again only
    /// at the quarters that border a cell of its size whose ray disagrees with its own (the side
    /// the shadow edge that marked it lies on); its other quarters take its visibility without a
    /// ray, unless [`CutSettings::far_quarters_through`] has them traced. With it through the
    /// first level and [`CutSettings::boundary_budget`] lowered to match, the bakes cast 22–33 %
    /// fewer rays than tracing every quarter, with less error against a ray per direction, on
    /// every mesh and map of `cargo bench --bench bake -- matrix` that refines shadow edges
    /// (docs/benchmarks.md).
    #[serde(default)]
    pub edge_quarters_from: u32,
    /// Through this boundary level (1 = the first; 0: none), where edge quarters are traced, a
    /// marked cell's other quarters are traced too when one of its edge quarters disagrees with
    /// it: the edge crosses into the cell, and in a wide cell it may bend away from the side that
    /// marked it.
    #[serde(default)]
    pub far_quarters_through: u32,
}

impl Default for CutSettings {
    fn default() -> Self {
        Self {
            epsilon: 0.02,
            max_cut: 1024,
            trace_leaves: 0,
            cell_leaves: 4,
            ray_offset: 1e-4,
            boundary_levels: 0,
            boundary_budget: 0.0015,
            cone_leaves: 0,
            rebuild_whole_passes: false,
            edge_quarters_from: 1,
            far_quarters_through: 1,
        }
    }
}

/// One vertex's cut.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct VertexCut {
    /// (node index, V_k), in pre-order.
    pub entries: Vec<(u32, f32)>,
    /// Rays cast for this vertex.
    pub rays: u64,
    /// ε actually used (> settings.epsilon when the cap forced coarsening).
    pub epsilon_used: f64,
    /// Interpolated from traced neighbours instead of traced (decision (f), [`super::sparse`]).
    pub interpolated: bool,
    /// What the vertex knows of each visibility cell, when asked for ([`Prior::record`]; empty
    /// otherwise): per 64 cells two words, the cells whose visibility along their ray is known
    /// exactly and, of those, the visible ones. Used while baking only (not stored in the bake).
    pub cell_bits: Vec<[u64; 2]>,
}

/// Per-thread scratch: the traced cell visibilities of the current vertex, keyed by (refinement
/// level, the cell's first leaf) (generation-stamped so that nothing is cleared between vertices).
pub struct CutScratch {
    /// Per cell key, one word: the generation that traced the cell (`>> 2`), whether it is
    /// marked for boundary refinement ([`MARKED`]) and whether its ray was unoccluded
    /// ([`VISIBLE`]); stamp, mark and answer share a word so that the marking's neighbour tests
    /// load one.
    cells: Vec<u32>,
    /// Per cell key, for a cell marked at a level whose quarters are edge quarters
    /// ([`CutSettings::edge_quarters_from`]): which of its neighbours ([`CellNeighbours::of`],
    /// bit j for the j-th, the 32nd on in bit 31) have the other visibility. Valid where the cell
    /// is marked for the current vertex.
    edge_masks: Vec<u32>,
    /// The quarters a level took from their cell without a ray that may yet be traced
    /// ([`CutSettings::far_quarters_through`]): (node, size, scratch key, the cell's key).
    held: Vec<(u32, u32, u32, u32)>,
    /// The keys of the cells whose traced edge quarters include one of the other visibility
    /// ([`trace_far_quarters`]), kept to reuse its allocation.
    crossed: Vec<u32>,
    /// Cells traced for the current vertex (boundary refinement only): (node, cell size, scratch
    /// key), so that the marking reads no tree node for them.
    traced: Vec<(u32, u32, u32)>,
    /// Cells to trace in one batch ([`trace_cells`]), kept to reuse its allocations.
    batch: Batch,
    /// Cells marked at one level with the light they gate ([`mark_boundaries`]), kept likewise.
    gated: Vec<(f64, usize)>,
    /// Per tree node, its cosine mass for the current vertex ([`node_weight`]), computed once and
    /// kept for the passes that boundary refinement and the cut cap make (stamped as `stamp`).
    weight: Vec<f64>,
    weight_stamp: Vec<u32>,
    /// Per tree node of at least `cell_leaves` leaves, its part of the cut as the last pass that
    /// built it left it ([`Memo`]), for the passes of boundary refinement, which rebuild only the
    /// subtrees where cells were marked (stamped as `stamp`; 0 where a merge above dropped it).
    memo: Vec<Memo>,
    memo_stamp: Vec<u32>,
    /// Every pass's finished cut of the current vertex, one after the other: what [`Memo`]
    /// ranges index.
    arena: Vec<(u32, f32)>,
    /// The current pass's memos, in the order their nodes finished: (node, its memo with the
    /// range in the pass's output).
    recorded: Vec<(u32, Memo)>,
    /// The cells the last [`mark_boundaries`] marked, in leaf order: (first leaf, end leaf, node).
    marked: Vec<(u32, u32, u32)>,
    /// Those of the first level, kept while the finer levels are traced: the pass after the last
    /// level rebuilds the subtrees that hold them.
    first_marked: Vec<(u32, u32, u32)>,
    /// The cut being built ([`vertex_cut`]), kept to reuse its allocation.
    entries: Vec<(u32, f32)>,
    /// The cosine masses a first pass's planning summed ([`node_weight`]), for its [`Planned`].
    masses: Vec<(u32, f64)>,
    generation: u32,
}

/// [`CutScratch::cells`]: the cell's ray was unoccluded.
const VISIBLE: u32 = 1;
/// [`CutScratch::cells`]: the cell is marked for boundary refinement.
const MARKED: u32 = 2;
/// The largest generation [`CutScratch::cells`] holds (two bits go to [`VISIBLE`] and
/// [`MARKED`]); past it every stamp is cleared.
const MAX_GENERATION: u32 = u32::MAX >> 2;

/// A node's part of a cut: a range of [`CutScratch::arena`] and the node's [`Sums`].
#[derive(Debug, Clone, Copy, Default)]
struct Memo {
    start: u32,
    end: u32,
    sums: Sums,
}

impl CutScratch {
    /// Scratch for a tree with `leaves` leaves and cuts with `boundary_levels` levels of boundary
    /// refinement.
    pub fn new(leaves: usize, boundary_levels: u32) -> Self {
        let n = leaves * (boundary_levels as usize + 1);
        Self {
            cells: vec![0; n],
            edge_masks: vec![0; n],
            held: Vec::new(),
            crossed: Vec::new(),
            traced: Vec::new(),
            batch: Batch::default(),
            gated: Vec::new(),
            weight: Vec::new(),
            weight_stamp: Vec::new(),
            memo: Vec::new(),
            memo_stamp: Vec::new(),
            arena: Vec::new(),
            recorded: Vec::new(),
            marked: Vec::new(),
            first_marked: Vec::new(),
            entries: Vec::new(),
            masses: Vec::new(),
            generation: 0,
        }
    }

    fn next_vertex(&mut self) {
        self.generation += 1;
        if self.generation > MAX_GENERATION {
            self.cells.iter_mut().for_each(|s| *s = 0);
            self.weight_stamp.iter_mut().for_each(|s| *s = 0);
            self.memo_stamp.iter_mut().for_each(|s| *s = 0);
            self.generation = 1;
        }
        self.clear_lists();
    }

    /// Takes up a vertex planned earlier ([`plan_first_pass`]) under its generation: what its plan
    /// stamped and no later vertex overwrote is still its own (the cosine masses above all). Every
    /// check is for equality with the generation, so going back to an older one is safe.
    fn resume_vertex(&mut self, generation: u32) {
        self.generation = generation;
        self.clear_lists();
    }

    /// Whether cell `key` was traced (or set) for the current vertex.
    #[inline]
    fn known(&self, key: usize) -> bool {
        self.cells[key] >> 2 == self.generation
    }

    /// Cell `key`'s visibility, if it was traced (or set) for the current vertex.
    #[inline]
    fn visibility(&self, key: usize) -> Option<bool> {
        let c = self.cells[key];
        (c >> 2 == self.generation).then_some(c & VISIBLE != 0)
    }

    /// Sets cell `key`'s visibility for the current vertex (unmarked).
    #[inline]
    fn set(&mut self, key: usize, visible: bool) {
        self.cells[key] = self.generation << 2 | visible as u32;
    }

    /// Whether cell `key` is marked for boundary refinement for the current vertex.
    #[inline]
    fn marked(&self, key: usize) -> bool {
        self.cells[key] >> 1 == (self.generation << 1 | 1)
    }

    fn clear_lists(&mut self) {
        self.traced.clear();
        self.arena.clear();
        self.recorded.clear();
    }
}

struct Ctx<'a> {
    tree: &'a LightTree,
    neighbours: &'a CellNeighbours,
    /// Cells smaller than this are traced only where they border the edge
    /// ([`CutSettings::edge_quarters_from`], as a size; 0: none).
    edge_quarters_below: usize,
    /// Edge quarters of at least this size ([`CutSettings::far_quarters_through`], as a size;
    /// `usize::MAX`: none) have their cell's other quarters traced where one of them disagrees
    /// with it.
    far_quarters_min: usize,
    tracer: &'a Tracer,
    apex: Vec3A,
    n: DVec3,
    nf: Vec3A,
    trace_leaves: usize,
    /// [`CutSettings::cone_leaves`].
    cone_leaves: usize,
    /// The end (leaf index) of the last node whose cells were traced as one batch.
    batched_end: u32,
    cell_leaves: usize,
    boundary_levels: u32,
    /// [`CutSettings::boundary_budget`].
    budget: f64,
    epsilon: f64,
    /// ε of the settings, kept when the cap relaxes `epsilon`: the blind guess of rule 3 uses it.
    guess_epsilon: f64,
    scratch: &'a mut CutScratch,
    rays: u64,
    /// Whether cone tests may be used (false on redo passes: their answers are cached in `free`).
    free: Vec<u32>,
    redo: bool,
    /// Whether this pass may take a subtree's part of the cut from its memo (the passes of
    /// boundary refinement; not the cut cap's, which change ε) and records memos.
    memo: bool,
    /// [`Prior::cell_ranges`] and [`Prior::agreed`].
    cell_ranges: &'a [(u32, u32)],
    agreed: &'a [[u64; 2]],
    /// [`Prior::root_hemisphere`].
    root_hemisphere: bool,
    /// The first pass is being planned ([`plan_first_pass`]): its cells are collected here, not
    /// traced, and the descent stops where they would be traced.
    plan: Option<Batch>,
    /// The first pass was planned and traced ahead ([`Planned`]): its cells are set and its cone
    /// answers are in `free`.
    planned: bool,
    /// The first pass is being planned: the cosine masses summed go to the scratch's `masses`.
    planning: bool,
}

/// Which visibility cells border which, for boundary refinement: per tree node that is a cell at
/// one of the refined sizes (`cell_leaves`, a quarter of it, …) or the quarters of the last, the
/// cells of the same size whose leaves touch its leaves in the cube map's 8-neighbourhood (across
/// face edges too), and the cell four times its size that holds it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CellNeighbours {
    offsets: Vec<u32>,
    list: Vec<u32>,
    /// The first leaf of each cell of `list`, beside it: the marking reads the neighbours' scratch
    /// keys without loading their tree nodes.
    firsts: Vec<u32>,
    /// Per tree node that is a cell at a size below `cell_leaves`, the cell four times its size
    /// that holds it ([`NO_CELL`] elsewhere), and that cell's first leaf.
    parent: Vec<u32>,
    parent_first: Vec<u32>,
    /// Per tree node that is a cell with a parent, which of its parent's neighbours its own
    /// neighbours lie in: bit j for the parent's j-th ([`CellNeighbours::of`]; the 32nd on in bit
    /// 31). A quarter borders the cells its parent's [`CutScratch::edge_masks`] bits name where the
    /// two masks meet.
    quarter_masks: Vec<u32>,
}

/// No cell's neighbours (planning a first pass needs none).
static NO_NEIGHBOURS: CellNeighbours = CellNeighbours {
    offsets: Vec::new(),
    list: Vec::new(),
    firsts: Vec::new(),
    parent: Vec::new(),
    parent_first: Vec::new(),
    quarter_masks: Vec::new(),
};

/// [`CellNeighbours::parent_first`]: no such cell.
const NO_CELL: u32 = u32::MAX;

impl CellNeighbours {
    /// Neighbours of the cells of `cell_leaves` leaves and of each quarter of it: the `levels`
    /// sizes that can be refined (at least 4 leaves) and the quarters of the last, which the last
    /// level traces ([`CutSettings::edge_quarters_from`] reads their neighbours). `levels` = 0
    /// gives an empty table.
    pub fn new(set: &DirectionSet, tree: &LightTree, cell_leaves: usize, levels: u32) -> Self {
        let nodes = tree.nodes();
        let texels = tree.leaf_texels();
        let leaves = texels.len();
        let mut lists: Vec<Vec<u32>> = vec![Vec::new(); nodes.len()];
        let mut parent = vec![NO_CELL; nodes.len()];
        if levels > 0 && leaves == set.len() {
            let mut leaf_of_texel = vec![0u32; leaves];
            for (l, &t) in texels.iter().enumerate() {
                leaf_of_texel[t as usize] = l as u32;
            }
            // A leaf's 8 neighbours: the texels whose centres lie one texel beyond its edges'
            // midpoints and its corners (reflected through them from its centre).
            let adjacent: Vec<[u32; 8]> = texels
                .iter()
                .map(|&t| {
                    let (c, d) = (set.texel_corners(t as usize), set.directions()[t as usize]);
                    let points = [
                        c[0],
                        c[1],
                        c[2],
                        c[3],
                        (c[0] + c[1]) * 0.5,
                        (c[1] + c[2]) * 0.5,
                        (c[2] + c[3]) * 0.5,
                        (c[3] + c[0]) * 0.5,
                    ];
                    points.map(|p| {
                        leaf_of_texel[set.texel_of((2.0 * p - d).try_normalize().unwrap_or(d))]
                    })
                })
                .collect();
            let mut size = cell_leaves;
            let mut cell_of_leaf = vec![u32::MAX; leaves];
            let mut coarser = vec![NO_CELL; leaves];
            // The refinable sizes, and the quarters of the last (the cells the levels trace).
            for level in 0..=levels {
                if level > 0 {
                    if size < 4 {
                        break;
                    }
                    size = (size / 4).max(1);
                    std::mem::swap(&mut coarser, &mut cell_of_leaf);
                }
                let cells = super::decisions::nodes_of_at_most(tree, size as u32, 0);
                for &k in &cells {
                    let node = nodes[k];
                    cell_of_leaf[node.first as usize..(node.first + node.count) as usize]
                        .fill(k as u32);
                    if level > 0 && coarser[node.first as usize] != k as u32 {
                        parent[k] = coarser[node.first as usize];
                    }
                }
                for k in cells {
                    let node = nodes[k];
                    let list = &mut lists[k];
                    for around in &adjacent[node.first as usize..(node.first + node.count) as usize]
                    {
                        for &nb in around {
                            let m = cell_of_leaf[nb as usize];
                            if m != k as u32 && !list.contains(&m) {
                                list.push(m);
                            }
                        }
                    }
                    list.sort_unstable();
                }
            }
        }
        let mut offsets = Vec::with_capacity(nodes.len() + 1);
        let mut list = Vec::new();
        offsets.push(0);
        for l in lists {
            list.extend(l);
            offsets.push(list.len() as u32);
        }
        let firsts = list.iter().map(|&m| nodes[m as usize].first).collect();
        let parent_first: Vec<u32> = parent
            .iter()
            .map(|&a| match a {
                NO_CELL => NO_CELL,
                a => nodes[a as usize].first,
            })
            .collect();
        let of = |k: usize| &list[offsets[k] as usize..offsets[k + 1] as usize];
        let quarter_masks = (0..nodes.len())
            .map(|q| {
                let a = parent[q];
                if a == NO_CELL {
                    return 0;
                }
                let around = of(a as usize);
                of(q).iter().fold(0u32, |mask, &m| {
                    match around.binary_search(&parent[m as usize]) {
                        Ok(j) => mask | 1 << j.min(31),
                        Err(_) => mask,
                    }
                })
            })
            .collect();
        Self {
            offsets,
            list,
            firsts,
            parent,
            parent_first,
            quarter_masks,
        }
    }

    /// The first leaves of [`CellNeighbours::of`]'s cells, in the same order.
    pub fn firsts_of(&self, k: usize) -> &[u32] {
        match (self.offsets.get(k), self.offsets.get(k + 1)) {
            (Some(&a), Some(&b)) => &self.firsts[a as usize..b as usize],
            _ => &[],
        }
    }

    /// The neighbours of cell `k` (empty for a node that is no refinable cell).
    pub fn of(&self, k: usize) -> &[u32] {
        match (self.offsets.get(k), self.offsets.get(k + 1)) {
            (Some(&a), Some(&b)) => &self.list[a as usize..b as usize],
            _ => &[],
        }
    }
}

/// Visibility a vertex takes from its traced neighbours instead of tracing ([`super::sparse`]), and
/// whether to record its own for others. `cells` lists the visibility cells (node, first leaf, end
/// leaf) in leaf order; `agreed` ([`VertexCut::cell_bits`]' layout) the cells whose visibility its
/// sampled neighbours all know and agree on ([`super::sparse::agreed_cells`]): each is set to it
/// before the cut is built, so its ray is not cast. The default takes and records nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct Prior<'a> {
    pub cells: &'a [(u32, u32, u32)],
    /// Per tree node, the range of `cells` under it ([`Prior::cell_ranges`]); needed with
    /// `agreed`.
    pub cell_ranges: &'a [(u32, u32)],
    pub agreed: &'a [[u64; 2]],
    /// Fill [`VertexCut::cell_bits`].
    pub record: bool,
    /// The root's cone test is decision (a)'s test of the vertex's hemisphere
    /// ([`super::decisions::hemisphere_free`]), as for an imported vertex; otherwise the root's
    /// cone is tested as any other node's.
    pub root_hemisphere: bool,
}

impl Prior<'_> {
    /// The cells of `cell_leaves` leaves (the largest nodes that small), in leaf order.
    pub fn cells(tree: &LightTree, cell_leaves: usize) -> Vec<(u32, u32, u32)> {
        let nodes = tree.nodes();
        super::decisions::nodes_of_at_most(tree, cell_leaves.max(1) as u32, 0)
            .into_iter()
            .map(|k| (k as u32, nodes[k].first, nodes[k].first + nodes[k].count))
            .collect()
    }

    /// Per tree node, the range of [`Prior::cells`]' `cells` whose leaves it holds (for a node
    /// above the cell size, exactly the cells under it).
    pub fn cell_ranges(tree: &LightTree, cells: &[(u32, u32, u32)]) -> Vec<(u32, u32)> {
        tree.nodes()
            .iter()
            .map(|node| {
                let lo = cells.partition_point(|c| c.1 < node.first);
                let hi = cells.partition_point(|c| c.1 < node.first + node.count);
                (lo as u32, hi as u32)
            })
            .collect()
    }
}

/// The light a shadow edge gates, for boundary refinement under a budget
/// ([`CutSettings::boundary_budget`]): per leaf ℓ the rotation-worst weight r_ℓ Ω_ℓ d_ℓ as prefix
/// sums over leaf order ([`super::refine::ring_weight_prefix`]: r_ℓ is the brightest luminance any
/// rotation about +Y brings to ℓ's elevation), and the vertex's hemisphere total Σ r_ℓ Ω_ℓ
/// max(d_ℓ·n, 0) ([`super::refine::HemisphereTotals`]). A cell's gated light is its share of that
/// sum: the most its visibility can move the vertex's irradiance under any rotation.
#[derive(Debug, Clone, Copy)]
pub struct LightGate<'a> {
    pub prefix: &'a [DVec3],
    pub total: f64,
}

/// [`VertexCut::cell_bits`] of a vertex just cut: a cell's visibility is known when its ray was
/// cast (its scratch stamp is this vertex's) or a cut node of V exactly 1 or 0 covers it (a free
/// cone, or cells merged that were all visible or all not); not where the cut guessed (V = ½),
/// splits it finer than a cell or has nothing (below the horizon).
fn cell_bits(
    scratch: &CutScratch,
    tree: &LightTree,
    entries: &[(u32, f32)],
    cells: &[(u32, u32, u32)],
) -> Vec<[u64; 2]> {
    let mut bits = vec![[0u64; 2]; cells.len().div_ceil(64)];
    let nodes = tree.nodes();
    let mut e = 0usize;
    for (i, &(_, first, end)) in cells.iter().enumerate() {
        let known = scratch.visibility(first as usize).or_else(|| {
            while e < entries.len()
                && nodes[entries[e].0 as usize].first + nodes[entries[e].0 as usize].count <= first
            {
                e += 1;
            }
            entries.get(e).and_then(|&(k, v)| {
                let node = &nodes[k as usize];
                let covers = node.first <= first && node.first + node.count >= end;
                match v {
                    _ if !covers => None,
                    1.0 => Some(true),
                    0.0 => Some(false),
                    _ => None,
                }
            })
        });
        if let Some(visible) = known {
            bits[i / 64][0] |= 1 << (i % 64);
            if visible {
                bits[i / 64][1] |= 1 << (i % 64);
            }
        }
    }
    bits
}

/// Marks for refinement each cell traced at size `cell` (entries of `scratch.traced` from `from`
/// on) that has a traced neighbour of the other visibility: a shadow edge runs through or beside
/// it. Under a [`LightGate`] with a budget β > 0, the marked cells are then taken in order of the
/// light they gate, least first, and unmarked while that light sums to at most β of the vertex's
/// total: a shadow edge across a dark part of every rotation of the map moves the irradiance by
/// no more than β altogether, and its rays go to the edges of the lights. Returns whether any
/// cell stays marked.
fn mark_boundaries(
    ctx: &mut Ctx,
    neighbours: &CellNeighbours,
    cell: usize,
    from: usize,
    gate: Option<LightGate>,
) -> bool {
    let (tree, base, n) = (ctx.tree, ctx.key(0, cell), ctx.n);
    // This level's quarters are edge quarters ([`inherited`]).
    let edge_quarters = (cell / 4).max(1) < ctx.edge_quarters_below;
    let scratch = &mut *ctx.scratch;
    let generation = scratch.generation;
    let budget = gate.map_or(0.0, |g| ctx.budget * g.total);
    scratch.gated.clear();
    let mut marked = 0usize;
    for i in from..scratch.traced.len() {
        let (k, c, own) = scratch.traced[i];
        if c as usize != cell {
            continue;
        }
        let own = own as usize;
        // A traced neighbour of the other visibility: its word is this vertex's stamp with the
        // other answer (marks aside).
        let other = (generation << 2 | (scratch.cells[own] & VISIBLE)) ^ VISIBLE;
        let cells = &scratch.cells;
        let firsts = neighbours.firsts_of(k as usize);
        let differs =
            |first: u32| cells.get(base + first as usize).map(|&c| c & !MARKED) == Some(other);
        let edge = if edge_quarters {
            // Every such neighbour: the quarters beside them are the ones traced.
            let mask = firsts
                .iter()
                .enumerate()
                .filter(|&(_, &first)| differs(first))
                .fold(0u32, |mask, (j, _)| mask | 1 << j.min(31));
            scratch.edge_masks[own] = mask;
            mask != 0
        } else {
            firsts.iter().any(|&first| differs(first))
        };
        if edge {
            scratch.cells[own] |= MARKED;
            marked += 1;
            if let Some(g) = gate.filter(|_| budget > 0.0) {
                // Only a cell gating at most the budget can be left coarse.
                let w = cell_gate(tree, g.prefix, k, n, budget);
                if w <= budget {
                    scratch.gated.push((w, own));
                }
            }
        }
    }
    if !scratch.gated.is_empty() {
        scratch
            .gated
            .sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut spent = 0.0;
        for &(w, key) in &scratch.gated {
            if spent + w > budget {
                break;
            }
            spent += w;
            scratch.cells[key] &= !MARKED;
            marked -= 1;
        }
    }
    // The marked cells' leaf ranges, for the next pass's memos.
    scratch.marked.clear();
    for i in from..scratch.traced.len() {
        let (k, c, own) = scratch.traced[i];
        if c as usize == cell && scratch.marked(own as usize) {
            let node = &tree.nodes()[k as usize];
            scratch
                .marked
                .push((node.first, node.first + node.count, k));
        }
    }
    scratch.marked.sort_unstable();
    marked > 0
}

/// The light cell `k` gates ([`LightGate`]): [`super::refine::hemisphere_weight`] over the cell,
/// Σ max(r Ω d·n, 0) over its leaves, summed leaf by leaf where the horizon crosses it (a shadow
/// edge along the horizon is common, and descending the cell's subtree loads a node for each of
/// its ~2× as many nodes, where the leaves' prefix sums lie together). Exact where it is at most
/// `limit`; above it, the sum may stop at a value above `limit` (Σ r Ω d·n over the cell, a lower
/// bound: the clamp only adds).
// Not inlined: inside the marking loop its running sum was kept on the stack, a store and a load
// per leaf.
#[inline(never)]
fn cell_gate(tree: &LightTree, prefix: &[DVec3], k: u32, n: DVec3, limit: f64) -> f64 {
    let node = &tree.nodes()[k as usize];
    if prefix.len() <= tree.leaf_count() || node.is_leaf() || node.count as usize > LEAF_SUM_MAX {
        return super::refine::hemisphere_weight(tree, prefix, k, 0, tree.leaf_count() as u32, n);
    }
    let (up, wholly_above) = node.above(n);
    let (first, end) = (node.first as usize, (node.first + node.count) as usize);
    if !up {
        0.0
    } else if wholly_above {
        (prefix[end] - prefix[first]).dot(n).max(0.0)
    } else {
        // (With a margin far above the rounding of the prefix sums' difference.)
        let lower = (prefix[end] - prefix[first]).dot(n);
        if lower > limit * (1.0 + 1e-9) {
            return lower;
        }
        prefix[first..=end]
            .windows(2)
            .map(|p| (p[1] - p[0]).dot(n).max(0.0))
            .sum()
    }
}

/// Whether a cell marked by the last [`mark_boundaries`] meets the leaves [first, end).
fn marked_within(marked: &[(u32, u32, u32)], first: u32, end: u32) -> bool {
    let i = marked.partition_point(|&(_, e, _)| e <= first);
    marked.get(i).is_some_and(|&(s, _, _)| s < end)
}

/// Ends a pass: its surviving memos ([`CutScratch::recorded`]) now index its cut, appended to the
/// arena.
fn finish_pass(ctx: &mut Ctx, entries: &[(u32, f32)]) {
    if !ctx.memo {
        return;
    }
    let s = &mut *ctx.scratch;
    let base = s.arena.len() as u32;
    for &(k, m) in &s.recorded {
        s.memo[k as usize] = Memo {
            start: base + m.start,
            end: base + m.end,
            sums: m.sums,
        };
        s.memo_stamp[k as usize] = s.generation;
    }
    s.recorded.clear();
    s.arena.extend_from_slice(entries);
}

/// (Σ Ω c, Σ Ω c V, error bound Σ Ω c |V_i − V_node|) of a subtree.
type Sums = (f64, f64, f64);

/// The cut of one vertex at `position` with unit `normal`.
#[allow(clippy::too_many_arguments)]
pub fn vertex_cut(
    position: DVec3,
    normal: DVec3,
    offset: f64,
    tree: &LightTree,
    tracer: &Tracer,
    settings: &CutSettings,
    neighbours: &CellNeighbours,
    scratch: &mut CutScratch,
    prior: Prior,
    gate: Option<LightGate>,
    planned: Option<(Planned, &GroupRays)>,
) -> VertexCut {
    let resume = planned.as_ref().map(|(p, _)| p.generation);
    let mut ctx = start_vertex(
        position, normal, offset, tree, tracer, settings, scratch, prior, resume, neighbours,
    );
    if let Some((planned, rays)) = planned {
        // The first pass's rays, traced ahead with other vertices': as `trace_batch` caches them.
        let s = &mut *ctx.scratch;
        for &(k, w) in &rays.masses[planned.masses.0 as usize..planned.masses.1 as usize] {
            s.weight[k as usize] = w;
            s.weight_stamp[k as usize] = s.generation;
        }
        let range = planned.rays.0 as usize..planned.rays.1 as usize;
        let cells = rays.cells[range.clone()].iter();
        let answers = rays.occluded[range.clone()]
            .iter()
            .zip(&rays.weights[range.clone()]);
        for (&(k, cell, key), (&occluded, &w)) in cells.zip(answers) {
            if ctx.boundary_levels > 0 {
                s.traced.push((k, cell, key));
            }
            s.set(key as usize, !occluded);
            if !w.is_nan() {
                s.weight[k as usize] = w;
                s.weight_stamp[k as usize] = s.generation;
            }
        }
        ctx.rays = range.len() as u64;
        ctx.free = planned.free;
        ctx.planned = true;
    }
    // Built in the scratch's buffer, which keeps its capacity from vertex to vertex; the cut is
    // copied out at its size at the end.
    let mut entries = std::mem::take(&mut ctx.scratch.entries);
    entries.clear();
    let top = ctx.cell_leaves;
    // A planned first pass has its rays and cone answers already, and the marking reads only
    // those: where boundary refinement follows, the first pass's cut is not built (the pass after
    // the levels is built whole instead of from its memos, the same cut), unless no cell is
    // marked; then it is built below as the first pass.
    let deferred = ctx.planned && ctx.memo;
    if !deferred {
        build(&mut ctx, 0, false, top, &mut entries);
        finish_pass(&mut ctx, &entries);
    }
    // Boundary refinement: cells beside a traced cell of the other visibility are traced again as
    // four cells half as wide, level after level, and the cut is then rebuilt once (cached rays
    // and cone answers are reused) where the first level marked cells; every finer level lies
    // within them.
    let (mut cell, mut from) = (top, 0);
    let mut refined = false;
    for _ in 0..ctx.boundary_levels {
        if cell < 4 || !mark_boundaries(&mut ctx, neighbours, cell, from, gate) {
            break;
        }
        from = ctx.scratch.traced.len();
        if !ctx.memo {
            // The reference: the whole cut rebuilt after each level, which traces the level.
            ctx.redo = true;
            entries.clear();
            build(&mut ctx, 0, false, top, &mut entries);
        } else {
            trace_marked(&mut ctx, cell);
            if !refined {
                let s = &mut *ctx.scratch;
                std::mem::swap(&mut s.first_marked, &mut s.marked);
                refined = true;
            }
        }
        cell /= 4;
    }
    if deferred {
        // No first pass left memos (and memos are stamped per vertex, so none would be taken):
        // the pass after the levels is built whole, recording none.
        ctx.memo = false;
    }
    if refined {
        let s = &mut *ctx.scratch;
        std::mem::swap(&mut s.first_marked, &mut s.marked);
        ctx.redo = true;
        entries.clear();
        build(&mut ctx, 0, false, top, &mut entries);
    } else if deferred {
        build(&mut ctx, 0, false, top, &mut entries);
    }
    ctx.memo = false;
    while entries.len() > settings.max_cut.max(1) && ctx.epsilon < 1.0 {
        ctx.epsilon = if ctx.epsilon > 0.0 {
            ctx.epsilon * 2.0
        } else {
            1e-3
        };
        ctx.redo = true;
        entries.clear();
        build(&mut ctx, 0, false, top, &mut entries);
    }
    let cell_bits = if prior.record {
        cell_bits(ctx.scratch, tree, &entries, prior.cells)
    } else {
        Vec::new()
    };
    let cut = entries.to_vec();
    ctx.scratch.entries = entries;
    VertexCut {
        entries: cut,
        rays: ctx.rays,
        epsilon_used: ctx.epsilon,
        interpolated: false,
        cell_bits,
    }
}

/// A vertex's first pass, planned ([`plan_first_pass`]): its rays, found before they are traced
/// so that the rays of many vertices go to the tracer in one call ([`GroupRays`]), and its cone
/// answers, for [`vertex_cut`] to take instead of tracing and testing again. The cut is the same as
/// without: which cells the first pass traces and which cones it tests does not depend on any
/// ray's answer.
#[derive(Debug, Clone, Default)]
pub struct Planned {
    /// The scratch's generation while planning, taken up again by [`vertex_cut`].
    generation: u32,
    /// The vertex's rays in its [`GroupRays`]: [start, end).
    rays: (u32, u32),
    /// The vertex's cosine masses in its [`GroupRays`]: [start, end).
    masses: (u32, u32),
    /// The nodes whose cone the first pass found free, sorted.
    free: Vec<u32>,
}

/// The first-pass rays of a group of neighbouring vertices ([`plan_first_pass`]), traced in one
/// call ([`Tracer::occluded_grouped`]).
#[derive(Debug, Clone, Default)]
pub struct GroupRays {
    /// (node, cell size, scratch key) of each ray's cell.
    cells: Vec<(u32, u32, u32)>,
    /// Each cell's cosine mass, as planning found it (NaN where not known): the scratch's cache
    /// of them does not outlive the other vertices of the group.
    weights: Vec<f64>,
    /// The other cosine masses each vertex's planning summed (node, mass), for its cut to take
    /// instead of summing them again: the group's later vertices overwrite the scratch's cache of
    /// them, their horizons crossing the same nodes.
    masses: Vec<(u32, f64)>,
    origins: Vec<Vec3A>,
    dirs: Vec<Vec3A>,
    occluded: Vec<bool>,
}

impl GroupRays {
    /// Empties it for the next group (keeping its allocations).
    pub fn clear(&mut self) {
        self.cells.clear();
        self.weights.clear();
        self.masses.clear();
        self.origins.clear();
        self.dirs.clear();
        self.occluded.clear();
    }

    /// Traces every ray planned into it ([`Tracer::occluded_grouped`]).
    pub fn trace(&mut self, tracer: &Tracer) {
        self.occluded.clear();
        self.occluded.resize(self.dirs.len(), false);
        tracer.occluded_grouped(&self.origins, &self.dirs, &mut self.occluded);
    }
}

/// The rays of [`vertex_cut`]'s first pass at this vertex, appended to `rays` untraced: the cut's
/// descent down to where it traces a node's cells, collecting them (`collect_cells`) instead, with
/// its cone tests (kept in the [`Planned`]). Plan a group's vertices with one scratch, trace
/// `rays` ([`GroupRays::trace`]), then cut each vertex with its plan and the same scratch, in the
/// order they were planned (each takes up its planning generation, and a later one's marks must
/// not precede it). The other arguments are `vertex_cut`'s.
#[allow(clippy::too_many_arguments)]
pub fn plan_first_pass(
    position: DVec3,
    normal: DVec3,
    offset: f64,
    tree: &LightTree,
    tracer: &Tracer,
    settings: &CutSettings,
    scratch: &mut CutScratch,
    prior: Prior,
    rays: &mut GroupRays,
) -> Planned {
    let mut ctx = start_vertex(
        position,
        normal,
        offset,
        tree,
        tracer,
        settings,
        scratch,
        prior,
        None,
        &NO_NEIGHBOURS,
    );
    ctx.plan = Some(take_batch(&mut ctx));
    ctx.planning = true;
    ctx.scratch.masses.clear();
    let top = ctx.cell_leaves;
    let mut out = std::mem::take(&mut ctx.scratch.entries);
    out.clear();
    build(&mut ctx, 0, false, top, &mut out);
    ctx.scratch.entries = out;
    let batch = ctx.plan.take().unwrap_or_default();
    let start = rays.cells.len() as u32;
    rays.cells.extend_from_slice(&batch.cells);
    rays.weights.extend_from_slice(&batch.weights);
    rays.dirs.extend_from_slice(&batch.dirs);
    rays.origins
        .extend(std::iter::repeat_n(ctx.apex, batch.dirs.len()));
    let masses_start = rays.masses.len() as u32;
    rays.masses.append(&mut ctx.scratch.masses);
    let planned = Planned {
        generation: ctx.scratch.generation,
        rays: (start, rays.cells.len() as u32),
        masses: (masses_start, rays.masses.len() as u32),
        free: std::mem::take(&mut ctx.free),
    };
    ctx.scratch.batch = batch;
    planned
}

/// A vertex's context with its scratch readied (a new generation, or `resume`'s): the cells taken
/// from the neighbours set.
#[allow(clippy::too_many_arguments)]
fn start_vertex<'a>(
    position: DVec3,
    normal: DVec3,
    offset: f64,
    tree: &'a LightTree,
    tracer: &'a Tracer,
    settings: &CutSettings,
    scratch: &'a mut CutScratch,
    prior: Prior<'a>,
    resume: Option<u32>,
    neighbours: &'a CellNeighbours,
) -> Ctx<'a> {
    match resume {
        Some(generation) => scratch.resume_vertex(generation),
        None => scratch.next_vertex(),
    }
    if scratch.weight_stamp.len() < tree.nodes().len() {
        scratch.weight.resize(tree.nodes().len(), 0.0);
        scratch.weight_stamp.resize(tree.nodes().len(), 0);
    }
    if settings.boundary_levels > 0
        && !settings.rebuild_whole_passes
        && scratch.memo_stamp.len() < tree.nodes().len()
    {
        scratch.memo.resize(tree.nodes().len(), Memo::default());
        scratch.memo_stamp.resize(tree.nodes().len(), 0);
    }
    for (w, &[known, visible]) in prior.agreed.iter().enumerate() {
        let mut rest = known;
        while rest != 0 {
            let i = w * 64 + rest.trailing_zeros() as usize;
            rest &= rest - 1;
            let Some(&(k, first, _)) = prior.cells.get(i) else {
                break;
            };
            // A top-level cell's scratch key is its first leaf ([`Ctx::key`]).
            scratch.set(first as usize, visible >> (i % 64) & 1 == 1);
            if settings.boundary_levels > 0 {
                // Taken as traced, so that a shadow edge beside it is refined (with rays).
                scratch
                    .traced
                    .push((k, settings.cell_leaves.max(1) as u32, first));
            }
        }
    }
    let apex = position + normal * offset;
    Ctx {
        tree,
        neighbours,
        edge_quarters_below: match settings.edge_quarters_from {
            0 => 0,
            l => settings.cell_leaves.max(1) >> (2 * (l - 1)).min(31),
        },
        far_quarters_min: match settings.far_quarters_through {
            0 => usize::MAX,
            l => (settings.cell_leaves.max(1) >> (2 * l).min(31)).max(1),
        },
        tracer,
        apex: apex.as_vec3().into(),
        n: normal,
        nf: normal.as_vec3().into(),
        trace_leaves: match settings.trace_leaves {
            0 => tree.leaf_count() / 2,
            t => t,
        }
        .max(settings.cell_leaves)
        .max(1),
        cone_leaves: settings.cone_leaves,
        batched_end: 0,
        cell_leaves: settings.cell_leaves.max(1),
        boundary_levels: settings.boundary_levels,
        budget: settings.boundary_budget.max(0.0),
        epsilon: settings.epsilon.max(0.0),
        guess_epsilon: settings.epsilon.max(0.0),
        scratch,
        rays: 0,
        free: Vec::new(),
        redo: false,
        memo: settings.boundary_levels > 0 && !settings.rebuild_whole_passes,
        cell_ranges: prior.cell_ranges,
        agreed: prior.agreed,
        root_hemisphere: prior.root_hemisphere,
        plan: None,
        planned: false,
        planning: false,
    }
}

impl Ctx<'_> {
    /// Scratch key of the cell of size `cell` whose first leaf is `first`: cells of different
    /// refinement levels may share a first leaf.
    #[inline]
    fn key(&self, first: u32, cell: usize) -> usize {
        if cell >= self.cell_leaves {
            return first as usize;
        }
        let level = ((self.cell_leaves / cell.max(1)).max(1).trailing_zeros() / 2) as usize;
        level * self.tree.leaf_count() + first as usize
    }

    /// Scratch key of the cell four times the size of cell `k` (of `cell` leaves) that holds it
    /// ([`CellNeighbours::parent_first`]; `None` for a cell with no parent).
    #[inline]
    fn parent_key(&self, k: usize, cell: usize) -> Option<usize> {
        match *self.neighbours.parent_first.get(k)? {
            NO_CELL => None,
            first => Some(self.key(first, cell * 4)),
        }
    }
}

/// Σ_i Ω_i c_i over the node's leaves, with Ω_i c_i = max(moment_i·n, 0) (exact for a leaf wholly
/// above the horizon; the leaf's mean cosine otherwise). A node of more than [`LEAF_SUM_MAX`]
/// leaves is split by its children's cones: a child wholly above gives its moment's projection,
/// one wholly below nothing, so only the band of leaves along the horizon is summed.
fn cosine_mass(tree: &LightTree, k: usize, n: DVec3) -> f64 {
    let node = &tree.nodes()[k];
    if node.count as usize > LEAF_SUM_MAX && !node.is_leaf() {
        let (up, wholly_above) = node.above(n);
        return if !up {
            0.0
        } else if wholly_above {
            node.moment.dot(n)
        } else {
            cosine_mass(tree, node.left as usize, n) + cosine_mass(tree, node.right as usize, n)
        };
    }
    let range = node.first as usize..(node.first + node.count) as usize;
    // Four running sums, so that the additions do not wait on each other (a single chain spent
    // most of its time on the adder's latency).
    let leaves = tree.leaf_moments().get(range).unwrap_or_default();
    let mut sums = [0.0f64; 4];
    let quads = leaves.chunks_exact(4);
    let rest = quads.remainder();
    for q in quads {
        for (s, m) in sums.iter_mut().zip(q) {
            *s += m.dot(n).max(0.0);
        }
    }
    rest.iter()
        .fold((sums[0] + sums[1]) + (sums[2] + sums[3]), |s, m| {
            s + m.dot(n).max(0.0)
        })
}

/// Nodes of at most this many leaves have their cosine mass summed leaf by leaf
/// ([`cosine_mass`]).
const LEAF_SUM_MAX: usize = 1024;

/// Σ_i Ω_i c_i over node `k`: its moment's projection when it lies wholly above the horizon, else
/// its leaves' ([`cosine_mass`]); once per node and vertex (the later passes read it back).
fn node_weight(ctx: &mut Ctx, k: usize, wholly_above: bool) -> f64 {
    if wholly_above {
        return ctx.tree.nodes()[k].moment.dot(ctx.n);
    }
    let s = &mut *ctx.scratch;
    if s.weight_stamp[k] == s.generation {
        return s.weight[k];
    }
    let w = cosine_mass(ctx.tree, k, ctx.n);
    s.weight[k] = w;
    s.weight_stamp[k] = s.generation;
    if ctx.planning {
        s.masses.push((k as u32, w));
    }
    w
}

/// The cell size below `node` in a traced subtree: a quarter of `cell` where the node is a cell
/// that [`mark_boundaries`] marked (a shadow edge crosses it), else `cell`.
fn cell_size(ctx: &Ctx, node: &crate::sphere::TreeNode, cell: usize) -> usize {
    let refined = ctx.boundary_levels > 0
        && node.count as usize <= cell
        && !node.is_leaf()
        && ctx.scratch.marked(ctx.key(node.first, cell));
    if refined { (cell / 4).max(1) } else { cell }
}

/// `cell`: the visibility cell size (leaves) in this subtree — `cell_leaves`, or a quarter of it
/// per boundary refinement.
fn build(ctx: &mut Ctx, k: usize, known: bool, cell: usize, out: &mut Vec<(u32, f32)>) -> Sums {
    let tree = ctx.tree;
    let node = &tree.nodes()[k];
    let (up, wholly_above) = node.above(ctx.n);
    if !up {
        return (0.0, 0.0, 0.0);
    }
    // A cell that a shadow edge crosses (marked by `mark_boundaries`) is traced as cells of a
    // quarter of its leaves instead.
    let cell = if known {
        cell_size(ctx, node, cell)
    } else {
        cell
    };
    if node.is_leaf() || (known && node.count as usize <= cell) {
        // A visibility cell: one ray along its mean direction (cached), V ∈ {0, 1} over the cell.
        let w = node_weight(ctx, k, wholly_above);
        if w <= 0.0 {
            return (0.0, 0.0, 0.0);
        }
        let v = if cell_visible(ctx, k, cell, node) {
            1.0
        } else {
            0.0
        };
        out.push((k as u32, v as f32));
        return (w, w * v, 0.0);
    }
    // A boundary pass rebuilds only the subtrees where the last level marked cells: elsewhere the
    // cut is what the pass before built (same cells, rays, cone answers and ε).
    let memo = ctx.memo && node.count as usize >= ctx.cell_leaves;
    if memo && ctx.redo {
        let s = &mut *ctx.scratch;
        if s.memo_stamp[k] == s.generation
            && !marked_within(&s.marked, node.first, node.first + node.count)
        {
            let m = s.memo[k];
            let start = out.len() as u32;
            out.extend_from_slice(&s.arena[m.start as usize..m.end as usize]);
            s.recorded.push((
                k as u32,
                Memo {
                    start,
                    end: out.len() as u32,
                    sums: m.sums,
                },
            ));
            return m.sums;
        }
    }
    // Every cell of a node above the cell size taken from the neighbours (rule 8): no cone test and
    // no rays, and where they are all alike and the node lies wholly above the horizon, the node
    // itself is the cut (the merge of its cells would give it).
    let agreed = if ctx.redo || cell != ctx.cell_leaves || node.count as usize <= cell {
        Agreed::Partly
    } else {
        agreed_over(ctx, k)
    };
    if let (Agreed::All(Some(visible)), true) = (agreed, wholly_above) {
        let w = node_weight(ctx, k, wholly_above);
        if w <= 0.0 {
            return (0.0, 0.0, 0.0);
        }
        let v = if visible { 1.0 } else { 0.0 };
        let start = out.len() as u32;
        out.push((k as u32, v as f32));
        let sums = (w, w * v, 0.0);
        if memo {
            let end = out.len() as u32;
            ctx.scratch
                .recorded
                .push((k as u32, Memo { start, end, sums }));
        }
        return sums;
    }
    // Cone tests above the traced nodes, and inside them down to `cone_leaves`; not where a cell
    // is taken as occluded from the neighbours. (What ends the descent here in a boundary pass —
    // the horizon, a free cone, a guess — [`reach_marked`] repeats: keep the two in step; the
    // test of boundary passes against whole rebuilds fails where they part.)
    let cone = agreed == Agreed::Partly
        && (!known || (ctx.cone_leaves > 0 && node.count as usize > ctx.cone_leaves));
    if cone {
        let free = if ctx.redo || ctx.planned {
            ctx.free.binary_search(&(k as u32)).is_ok()
        } else {
            let test = || {
                ctx.tracer.cone_free(
                    ctx.apex,
                    ctx.nf,
                    node.mean_direction.as_vec3().into(),
                    node.cone_cos as f32,
                )
            };
            // The root's cone holds every leaf direction, so decision (a)'s test of the whole
            // hemisphere answers for it (a free hemisphere frees the root's cone; the converse can
            // fail only for geometry seen between the leaf directions, which then gets rays).
            let f = if k == 0 && ctx.root_hemisphere {
                let f = ctx.tracer.cone_free(ctx.apex, ctx.nf, ctx.nf, 0.0);
                debug_assert!(!f || test(), "a free hemisphere with a blocked root cone");
                f
            } else {
                test()
            };
            if f {
                ctx.free.push(k as u32);
            }
            f
        };
        if free {
            let w = node_weight(ctx, k, wholly_above);
            if w <= 0.0 {
                return (0.0, 0.0, 0.0);
            }
            out.push((k as u32, 1.0));
            return (w, w, 0.0);
        }
    }
    // (With the settings' ε, not the one the cap relaxed: a relaxed ε of 0.13 would accept the
    // whole sphere with V = ½, its error bound diluted by the half below the horizon. The cap
    // coarsens by merging, which keeps each node's cosine-weighted mean.)
    if !known && 0.5 * node.horizon(ctx.n).0 <= 4.0 * ctx.guess_epsilon {
        // A node so close to the horizon that even a blind guess V = ½ keeps its mean |Ṽ| error
        // within ε (½ Σ Ω c ≤ ε Ω) needs no rays. The O(1) bound Σ Ω c ≤ max cos · Ω screens
        // candidates.
        let w = node_weight(ctx, k, wholly_above);
        if w <= 0.0 {
            return (0.0, 0.0, 0.0);
        }
        if 0.5 * w <= ctx.guess_epsilon * node.solid_angle {
            out.push((k as u32, 0.5));
            return (w, 0.5 * w, 0.5 * w);
        }
    }
    let known_below = known || node.count as usize <= ctx.trace_leaves;
    // Packets in the first pass: its cells tile the hemisphere in leaf order, so a packet's rays
    // point alike. (Boundary refinement's cells are traced before the pass that builds them, by
    // [`trace_marked`], in packets of the quarters of marked cells; one at a time in the
    // reference of whole rebuilds.) With cone tests inside traced nodes, the packets are the
    // cells of the first node small enough not to be tested.
    let batch = if ctx.cone_leaves > 0 {
        // Nodes come in leaf order: one that starts before the last batch's end lies inside it.
        known_below && node.count as usize <= ctx.cone_leaves && node.first >= ctx.batched_end
    } else {
        known_below && !known
    };
    if batch && !ctx.redo && !matches!(agreed, Agreed::All(_)) {
        if let Some(mut plan) = ctx.plan.take() {
            // Planning the first pass: these are its rays, and nothing below depends on them.
            collect_cells(ctx, k, cell, &mut plan);
            ctx.plan = Some(plan);
            return (0.0, 0.0, 0.0);
        }
        if !ctx.planned {
            trace_cells(ctx, k, cell);
        }
        ctx.batched_end = node.first + node.count;
    }
    let known = known_below;
    let start = out.len();
    prefetch(tree.nodes(), node.right as usize);
    let (wl, vl, dl) = build(ctx, node.left as usize, known, cell, out);
    let mid = out.len();
    let (wr, vr, dr) = build(ctx, node.right as usize, known, cell, out);
    let w = wl + wr;
    if w <= 0.0 {
        out.truncate(start);
        forget_memos(ctx, start);
        return (0.0, 0.0, 0.0);
    }
    let v_parent = (vl + vr) / w;
    let dev = dl + dr + (vl - wl * v_parent).abs() + (vr - wr * v_parent).abs();
    let mergeable = mid - start <= 1 && out.len() - mid <= 1;
    if mergeable && dev <= ctx.epsilon * node.solid_angle {
        out.truncate(start);
        forget_memos(ctx, start);
        out.push((k as u32, v_parent as f32));
    }
    let sums = (w, vl + vr, dev);
    if memo {
        let (start, end) = (start as u32, out.len() as u32);
        ctx.scratch
            .recorded
            .push((k as u32, Memo { start, end, sums }));
    }
    sums
}

/// A merge replaced the pass's output from `start` on: the memos of the subtrees it held (the
/// last ones recorded) no longer index anything, and any older memo of theirs may be stale.
fn forget_memos(ctx: &mut Ctx, start: usize) {
    let s = &mut *ctx.scratch;
    while let Some(&(k, m)) = s.recorded.last() {
        if (m.start as usize) < start {
            break;
        }
        s.memo_stamp[k as usize] = 0;
        s.recorded.pop();
    }
}

/// Traces, in packets ([`Tracer::occluded_from`]), every visibility cell under node `k` that
/// [`build`] will ask [`cell_visible`] for (the same descent: above the horizon, with cosine mass,
/// split where marked for refinement) and has not been traced yet, and caches the answers: the
/// cells come in leaf order, so a packet's rays point alike.
fn trace_cells(ctx: &mut Ctx, k: usize, cell: usize) {
    let mut cells = take_batch(ctx);
    collect_cells(ctx, k, cell, &mut cells);
    trace_batch(ctx, cells);
}

/// The scratch's batch, emptied, for [`collect_cells`] to fill and [`trace_batch`] to trace.
fn take_batch(ctx: &mut Ctx) -> Batch {
    let mut batch = std::mem::take(&mut ctx.scratch.batch);
    batch.cells.clear();
    batch.dirs.clear();
    batch.weights.clear();
    batch
}

/// Cells to trace: (node, cell size, scratch key), each one's ray direction (its node's mean
/// direction) and, once traced, whether the ray was occluded.
#[derive(Default)]
struct Batch {
    cells: Vec<(u32, u32, u32)>,
    dirs: Vec<Vec3A>,
    /// Each cell's cosine mass ([`node_weight`]; NaN where not known).
    weights: Vec<f64>,
    occluded: Vec<bool>,
}

/// Traces the batch's cells, in that order, in packets ([`Tracer::occluded_from`]), caches the
/// answers, and gives the batch back to the scratch.
fn trace_batch(ctx: &mut Ctx, mut batch: Batch) {
    batch.occluded.clear();
    batch.occluded.resize(batch.cells.len(), false);
    ctx.tracer
        .occluded_from(ctx.apex, &batch.dirs, &mut batch.occluded);
    let s = &mut *ctx.scratch;
    for (&(k, cell, key), &occluded) in batch.cells.iter().zip(&batch.occluded) {
        if ctx.boundary_levels > 0 {
            s.traced.push((k, cell, key));
        }
        s.set(key as usize, !occluded);
    }
    ctx.rays += batch.cells.len() as u64;
    s.batch = batch;
}

/// Traces the quarters of every cell of size `cell` that the last [`mark_boundaries`] marked, of
/// those the pass after the marking would reach, as [`build`] would trace them (above the horizon
/// and with cosine mass), in packets ([`Tracer::occluded_from`]; the quarters of a cell, and of
/// the cells next in leaf order, point alike). At the first level they are found by descending
/// from the root as that pass would ([`reach_marked`]: a cell taken from the neighbours may lie
/// under a free cone or a guess); at the finer levels every marked cell is a quarter of a cell
/// reached.
fn trace_marked(ctx: &mut Ctx, cell: usize) {
    let mut cells = take_batch(ctx);
    if cell == ctx.cell_leaves {
        reach_marked(ctx, 0, false, &mut cells);
    } else {
        for i in 0..ctx.scratch.marked.len() {
            let k = ctx.scratch.marked[i].2;
            collect_cells(ctx, k as usize, cell, &mut cells);
        }
    }
    trace_batch(ctx, cells);
    if !ctx.scratch.held.is_empty() {
        trace_far_quarters(ctx);
    }
}

/// [`CutSettings::far_quarters_through`], after a level's edge quarters are traced: the quarters
/// held back ([`CutScratch::held`]) of each cell whose traced quarters include one of the other
/// visibility are traced too.
fn trace_far_quarters(ctx: &mut Ctx) {
    // The cells whose edge quarters disagree with them: the quarters just traced are the batch's.
    let mut crossed = std::mem::take(&mut ctx.scratch.crossed);
    crossed.clear();
    let s = &*ctx.scratch;
    for &(k, c, key) in &s.batch.cells {
        if let Some(a) = ctx.parent_key(k as usize, c as usize)
            && s.visibility(a) != s.visibility(key as usize)
        {
            crossed.push(a as u32);
        }
    }
    crossed.sort_unstable();
    crossed.dedup();
    let held = std::mem::take(&mut ctx.scratch.held);
    let mut cells = take_batch(ctx);
    for &(k, c, key, a) in &held {
        if crossed.binary_search(&a).is_ok() {
            let node = &ctx.tree.nodes()[k as usize];
            let w = node_weight(ctx, k as usize, node.above(ctx.n).1);
            cells.cells.push((k, c, key));
            cells.dirs.push(node.mean_direction.as_vec3().into());
            cells.weights.push(w);
        }
    }
    let s = &mut *ctx.scratch;
    (s.held, s.crossed) = (held, crossed);
    s.held.clear();
    trace_batch(ctx, cells);
}

/// The quarters of the cells of the first level that [`mark_boundaries`] marked, where the pass
/// after it reaches them: the descent of [`build`] in a boundary pass (below the horizon, a free
/// cone or a guess ends it) into the subtrees that hold a marked cell.
fn reach_marked(ctx: &mut Ctx, k: usize, known: bool, out: &mut Batch) {
    let tree = ctx.tree;
    let node = &tree.nodes()[k];
    let (up, wholly_above) = node.above(ctx.n);
    if !up || !marked_within(&ctx.scratch.marked, node.first, node.first + node.count) {
        return;
    }
    let top = ctx.cell_leaves;
    if node.is_leaf() || (known && node.count as usize <= top) {
        if cell_size(ctx, node, top) < top {
            collect_cells(ctx, k, top, out);
        }
        return;
    }
    let cone = !known || (ctx.cone_leaves > 0 && node.count as usize > ctx.cone_leaves);
    if cone && ctx.free.binary_search(&(k as u32)).is_ok() {
        return;
    }
    if !known && 0.5 * node.horizon(ctx.n).0 <= 4.0 * ctx.guess_epsilon {
        let w = node_weight(ctx, k, wholly_above);
        if w <= 0.0 || 0.5 * w <= ctx.guess_epsilon * node.solid_angle {
            return;
        }
    }
    let known = known || node.count as usize <= ctx.trace_leaves;
    reach_marked(ctx, node.left as usize, known, out);
    reach_marked(ctx, node.right as usize, known, out);
}

/// The cells [`trace_cells`] traces, in leaf order.
fn collect_cells(ctx: &mut Ctx, k: usize, cell: usize, out: &mut Batch) {
    let tree = ctx.tree;
    let node = &tree.nodes()[k];
    let (up, wholly_above) = node.above(ctx.n);
    if !up {
        return;
    }
    let cell = cell_size(ctx, node, cell);
    if node.is_leaf() || node.count as usize <= cell {
        let w = node_weight(ctx, k, wholly_above);
        let key = ctx.key(node.first, cell);
        if w > 0.0 && !ctx.scratch.known(key) {
            if let Some(v) = inherited(ctx, k, cell) {
                ctx.scratch.set(key, v);
                if cell >= ctx.far_quarters_min
                    && let Some(a) = ctx.parent_key(k, cell)
                {
                    ctx.scratch
                        .held
                        .push((k as u32, cell as u32, key as u32, a as u32));
                }
                return;
            }
            out.cells.push((k as u32, cell as u32, key as u32));
            out.dirs.push(node.mean_direction.as_vec3().into());
            out.weights.push(w);
        }
        return;
    }
    if cell == ctx.cell_leaves && matches!(agreed_over(ctx, k), Agreed::All(_)) {
        // Every cell below taken from the neighbours: nothing to trace.
        return;
    }
    prefetch(tree.nodes(), node.right as usize);
    collect_cells(ctx, node.left as usize, cell, out);
    collect_cells(ctx, node.right as usize, cell, out);
}

/// Asks the CPU to load node `k` (its first two cache lines: the node's 88 bytes unless it starts
/// late in a line) while the left subtree is walked: in pre-order the left child is the next node,
/// the right one far away, and the walks wait on their nodes' loads (`perf`: most of
/// `collect_cells`' samples fall just after one; measured in docs/benchmarks.md, "Prefetching the
/// right child").
#[inline(always)]
fn prefetch(nodes: &[crate::sphere::TreeNode], k: usize) {
    const { assert!(std::mem::size_of::<crate::sphere::TreeNode>() > 64) };
    #[cfg(target_arch = "x86_64")]
    if let Some(node) = nodes.get(k) {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let p = (node as *const crate::sphere::TreeNode).cast::<i8>();
        // Safety: a prefetch never faults, and both addresses lie inside `node`.
        unsafe {
            _mm_prefetch::<_MM_HINT_T0>(p);
            _mm_prefetch::<_MM_HINT_T0>(p.add(64));
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (nodes, k);
}

/// A quarter `k` (of `cell` leaves) of a cell that boundary refinement marked, at a level from
/// [`CutSettings::edge_quarters_from`] on, takes the cell's visibility without a ray (`Some`)
/// unless it borders a cell of the marked one's size whose visibility, traced or taken, differs
/// (the shadow edge that marked it lies on that side; `None`: trace it).
fn inherited(ctx: &Ctx, k: usize, cell: usize) -> Option<bool> {
    if cell >= ctx.edge_quarters_below {
        return None;
    }
    let a = ctx.parent_key(k, cell)?;
    let s = &*ctx.scratch;
    let v = s.visibility(a)?;
    let near = s.edge_masks[a] & ctx.neighbours.quarter_masks[k] != 0;
    if near { None } else { Some(v) }
}

/// What the cells under node `k` (a node above the cell size) take from the neighbours
/// ([`Prior::agreed`]).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Agreed {
    /// Not every cell, and none of them occluded.
    Partly,
    /// Not every cell, and at least one occluded: the node's cone is not worth testing.
    PartlyOccluded,
    /// Every cell, all visible (`Some(true)`), all occluded (`Some(false)`) or mixed (`None`).
    All(Option<bool>),
}

fn agreed_over(ctx: &Ctx, k: usize) -> Agreed {
    if ctx.agreed.is_empty() {
        return Agreed::Partly;
    }
    let (lo, hi) = ctx.cell_ranges[k];
    let (lo, hi) = (lo as usize, hi as usize);
    let (mut all_known, mut all_visible, mut any_visible, mut any_occluded) =
        (true, true, false, false);
    let mut i = lo;
    while i < hi {
        let bit = i % 64;
        let n = (64 - bit).min(hi - i);
        let mask = if n == 64 {
            !0u64
        } else {
            ((1u64 << n) - 1) << bit
        };
        let Some(&[known, visible]) = ctx.agreed.get(i / 64) else {
            return Agreed::Partly;
        };
        all_known &= known & mask == mask;
        all_visible &= visible & mask == mask;
        any_visible |= visible & mask != 0;
        any_occluded |= known & !visible & mask != 0;
        i += n;
    }
    if !all_known {
        return if any_occluded {
            Agreed::PartlyOccluded
        } else {
            Agreed::Partly
        };
    }
    Agreed::All(if all_visible {
        Some(true)
    } else if !any_visible {
        Some(false)
    } else {
        None
    })
}

/// Visibility of a cell (tree node `k`, of cell size `cell`) along its mean direction, traced once
/// per vertex and cached ([`trace_cells`] traces them ahead in packets).
fn cell_visible(ctx: &mut Ctx, k: usize, cell: usize, node: &crate::sphere::TreeNode) -> bool {
    let key = ctx.key(node.first, cell);
    let s = &mut *ctx.scratch;
    if let Some(visible) = s.visibility(key) {
        return visible;
    }
    let d = node.mean_direction;
    if let Some(plan) = &mut ctx.plan {
        // Planning the first pass: a ray to trace (its answer is not needed yet).
        plan.cells.push((k as u32, cell as u32, key as u32));
        plan.dirs.push(d.as_vec3().into());
        plan.weights.push(f64::NAN);
        // Its answer comes with the group's rays ([`vertex_cut`] sets it).
        s.set(key, true);
        return true;
    }
    if let Some(v) = inherited(ctx, k, cell)
        && (cell < ctx.far_quarters_min || !edge_quarter_differs(ctx, k, cell, v))
    {
        ctx.scratch.set(key, v);
        return v;
    }
    let s = &mut *ctx.scratch;
    if ctx.boundary_levels > 0 {
        s.traced.push((k as u32, cell as u32, key as u32));
    }
    let visible = !ctx.tracer.occluded(ctx.apex, d.as_vec3().into());
    ctx.rays += 1;
    s.set(key, visible);
    visible
}

/// [`CutSettings::far_quarters_through`] where the cut is rebuilt whole after every level (its
/// reference, [`CutSettings::rebuild_whole_passes`]): whether an edge quarter (of `cell` leaves,
/// above the horizon, with cosine mass) of the cell that holds quarter `k` has a visibility other
/// than the cell's `v`; they are traced as needed, as [`trace_marked`] traces them before
/// [`trace_far_quarters`] looks.
fn edge_quarter_differs(ctx: &mut Ctx, k: usize, cell: usize, v: bool) -> bool {
    let tree = ctx.tree;
    let mut stack = vec![ctx.neighbours.parent[k] as usize];
    while let Some(q) = stack.pop() {
        let node = &tree.nodes()[q];
        let (up, wholly_above) = node.above(ctx.n);
        if !up {
            continue;
        }
        if !node.is_leaf() && node.count as usize > cell {
            stack.extend([node.right as usize, node.left as usize]);
            continue;
        }
        if q != k
            && node_weight(ctx, q, wholly_above) > 0.0
            && inherited(ctx, q, cell).is_none()
            && cell_visible(ctx, q, cell, node) != v
        {
            return true;
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The light a cell gates, summed leaf by leaf where the horizon crosses it, against the
    /// descent of `hemisphere_weight` (each wholly-above subtree by its prefix sums): the same up
    /// to rounding, for the cells of every refinable size under random normals and weights, many
    /// of them crossed by the horizon.
    #[test]
    fn a_cell_gates_what_the_hemisphere_weight_gives() {
        let tree = LightTree::build(&DirectionSet::cube(32).unwrap());
        let mut rng = crate::math::Rng::new(11);
        let mut prefix = vec![DVec3::ZERO];
        for (d, &omega) in tree.leaf_directions().iter().zip(tree.leaf_solid_angles()) {
            let last = prefix[prefix.len() - 1];
            prefix.push(last + *d * omega * (0.1 + 10.0 * rng.next_f64()));
        }
        let mut crossed = 0;
        for size in [64u32, 16, 4] {
            let cells = crate::bake::decisions::nodes_of_at_most(&tree, size, 0);
            for trial in 0..200 {
                let k = cells[(rng.next_u64() % cells.len() as u64) as usize];
                // Every other normal points at the cell's edge: the horizon crosses it.
                let n = if trial % 2 == 0 {
                    let d = tree.nodes()[k].mean_direction;
                    let t = rng.unit_vector().cross(d).normalize();
                    (t + d * 0.05 * (rng.next_f64() - 0.5)).normalize()
                } else {
                    rng.unit_vector()
                };
                let want = crate::bake::refine::hemisphere_weight(
                    &tree,
                    &prefix,
                    k as u32,
                    0,
                    tree.leaf_count() as u32,
                    n,
                );
                let got = cell_gate(&tree, &prefix, k as u32, n, f64::INFINITY);
                assert!(
                    (got - want).abs() <= 1e-12 * want.abs().max(1e-9),
                    "cell {k} ({size} leaves), n {n:?}: {got} against {want}"
                );
                let (max_cos, wholly_above) = tree.nodes()[k].horizon(n);
                crossed += (max_cos > 0.0 && !wholly_above && want > 0.0) as usize;
            }
        }
        assert!(crossed >= 150, "{crossed} cells crossed by the horizon");
    }

    /// The cosine mass of nodes above [`LEAF_SUM_MAX`] leaves, split by the children's cones,
    /// against the sum over every leaf (the definition): the same up to rounding, for the root and
    /// random nodes under random normals, at 64 directions a side (root 24,576 leaves).
    #[test]
    fn split_cosine_mass_is_the_leaf_sum() {
        let tree = LightTree::build(&DirectionSet::cube(64).unwrap());
        let mut rng = crate::math::Rng::new(3);
        let mut split = 0;
        for trial in 0..400 {
            let n = rng.unit_vector();
            let k = if trial % 4 == 0 {
                0
            } else {
                (rng.next_u64() % tree.nodes().len() as u64) as usize
            };
            let node = tree.nodes()[k];
            let range = node.first as usize..(node.first + node.count) as usize;
            let want: f64 = tree.leaf_moments()[range]
                .iter()
                .map(|m| m.dot(n).max(0.0))
                .sum();
            let got = cosine_mass(&tree, k, n);
            assert!(
                (got - want).abs() <= 1e-12 * node.solid_angle.max(1.0),
                "node {k} ({} leaves), n {n:?}: {got} against {want}",
                node.count
            );
            split += (node.count as usize > LEAF_SUM_MAX) as usize;
        }
        assert!(split >= 100, "{split} nodes split");
    }

    /// The neighbour table against geometry: at each size, two cells are listed as neighbours
    /// exactly when some leaf of one lies within about a texel and a half (centre to centre) of a
    /// leaf of the other, and the relation is symmetric.
    #[test]
    fn cell_neighbours_are_the_cells_whose_leaves_touch() {
        let set = DirectionSet::cube(16).unwrap();
        let tree = LightTree::build(&set);
        let table = CellNeighbours::new(&set, &tree, 16, 2);
        let nodes = tree.nodes();
        let texel = set.texel_angle();
        // The two refinable sizes and the quarters of the last, which the last level traces.
        for size in [16usize, 4, 1] {
            // The cells of this size: the largest nodes of at most `size` leaves.
            let cells = crate::bake::decisions::nodes_of_at_most(&tree, size as u32, 0);
            // Each cell's parent: the cell four times its size that holds its leaves.
            let coarser = crate::bake::decisions::nodes_of_at_most(&tree, 4 * size as u32, 0);
            for &a in &cells {
                let want = if size == 16 {
                    NO_CELL
                } else {
                    let node = nodes[a];
                    let p = coarser
                        .iter()
                        .map(|&p| &nodes[p])
                        .find(|p| p.first <= node.first && node.first < p.first + p.count)
                        .unwrap();
                    assert!(node.first + node.count <= p.first + p.count);
                    p.first
                };
                assert_eq!(table.parent_first[a], want, "size {size}: cell {a}");
                // Which of the parent's neighbours the cell borders: those holding one of its own.
                let mask = if size == 16 {
                    0
                } else {
                    let p = coarser
                        .iter()
                        .copied()
                        .find(|&p| nodes[p].first == want)
                        .unwrap();
                    let around = table.of(p);
                    assert!(around.len() <= 31, "cell {p}: {} neighbours", around.len());
                    let holds = |c: u32, m: u32| {
                        let (c, m) = (&nodes[c as usize], &nodes[m as usize]);
                        c.first <= m.first && m.first < c.first + c.count
                    };
                    (0..around.len())
                        .filter(|&j| table.of(a).iter().any(|&m| holds(around[j], m)))
                        .fold(0u32, |mask, j| mask | 1 << j)
                };
                assert_eq!(table.quarter_masks[a], mask, "size {size}: cell {a}");
            }
            let leaves = |k: usize| {
                (nodes[k].first..nodes[k].first + nodes[k].count)
                    .map(|l| tree.leaf_directions()[l as usize])
                    .collect::<Vec<_>>()
            };
            let mut listed = 0;
            for &a in &cells {
                let firsts: Vec<u32> = table
                    .of(a)
                    .iter()
                    .map(|&m| nodes[m as usize].first)
                    .collect();
                assert_eq!(table.firsts_of(a), firsts, "cell {a}: first leaves");
                let la = leaves(a);
                for &b in &cells {
                    if a == b {
                        continue;
                    }
                    let lb = leaves(b);
                    let closest = la
                        .iter()
                        .flat_map(|x| lb.iter().map(move |y| x.dot(*y).clamp(-1.0, 1.0).acos()))
                        .fold(f64::INFINITY, f64::min);
                    let near = table.of(a).contains(&(b as u32));
                    assert_eq!(
                        near,
                        table.of(b).contains(&(a as u32)),
                        "not symmetric: {a} {b}"
                    );
                    // Edge neighbours are about a nominal texel apart, diagonal ones ~1.41 (up to
                    // 1.63 at face centres, where texels are widest); leaves two steps away are ≥
                    // 1.2 texels apart even at cube corners, where texels are narrowest.
                    if closest < 0.9 * texel {
                        assert!(
                            near,
                            "size {size}: cells {a} and {b} have leaves {closest} apart but are not neighbours"
                        );
                    }
                    if near {
                        listed += 1;
                        assert!(
                            closest < 1.8 * texel,
                            "size {size}: cells {a} and {b} listed but {:.2} texels apart",
                            closest / texel
                        );
                    }
                }
            }
            assert!(
                listed >= 3 * cells.len(),
                "size {size}: {listed} neighbour pairs for {} cells",
                cells.len()
            );
        }
        // No levels, no table.
        assert!(CellNeighbours::new(&set, &tree, 16, 0).of(5).is_empty());
    }
}
