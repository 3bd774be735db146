//! Every vertex's cut, packed: [`Cuts`] (6 bytes a cut node), and [`PartialBake`], the cuts of a
//! bake in progress, which the baker fills as vertices finish, in any order.
//!
//! Inputs: per-vertex cuts ([`VertexCut`], (node, V) in pre-order) as they are made. Outputs: the
//! packed cuts a [`super::Bake`] carries, the renderers read and [`super::file`] stores.
//!
//! Invariants: a vertex's entries are contiguous, in pre-order; V is quantised to 16 bits (error ≤
//! 7.6e-6) when stored, so what a later step reads back (refinement, interpolation) is what the bake
//! keeps; equality and the file's bytes do not depend on the order the vertices were stored in.
//! Memory: a batch of cuts is packed as soon as it is made (in parallel,
//! [`PartialBake::store_many`]), so a whole bake never holds the unpacked form of more than a batch
//! of vertices (at 1.6 M triangles that form was ~330 MiB beside the packed 237 MiB).

use super::VertexCut;

/// Cuts of all vertices: per vertex a span of `nodes` and `visibility`.
#[derive(Debug, Clone, Default)]
pub struct Cuts {
    /// Per vertex: [first, end) into `nodes` and `visibility` (empty for a vertex without a cut).
    /// Spans need not follow the vertex order (a bake stores vertices as they finish).
    spans: Vec<[u32; 2]>,
    /// Light-tree node indices, pre-order within each vertex.
    nodes: Vec<u32>,
    /// V_k quantised to u16 (V = q / 65535).
    visibility: Vec<u16>,
}

impl PartialEq for Cuts {
    /// The same cut at every vertex, however they are laid out.
    fn eq(&self, other: &Self) -> bool {
        self.vertex_count() == other.vertex_count()
            && (0..self.vertex_count()).all(|v| {
                self.nodes_of(v) == other.nodes_of(v) && self.quantised(v) == other.quantised(v)
            })
    }
}

impl Cuts {
    /// `vertex_count` vertices, each with an empty cut.
    pub fn with_vertices(vertex_count: usize) -> Self {
        Self {
            spans: vec![[0, 0]; vertex_count],
            nodes: Vec::new(),
            visibility: Vec::new(),
        }
    }

    /// Packs per-vertex cuts (one per vertex, in vertex order).
    pub fn from_vertex_cuts(cuts: &[VertexCut]) -> Self {
        let mut out = Self::with_vertices(cuts.len());
        let entries = cuts.iter().map(|c| c.entries.len()).sum();
        out.nodes.reserve_exact(entries);
        out.visibility.reserve_exact(entries);
        for (v, c) in cuts.iter().enumerate() {
            out.set(v, &c.entries);
        }
        out
    }

    /// Cuts in compressed row storage (`offsets[v]..offsets[v + 1]` is vertex v's, ascending from
    /// 0, as [`super::file`] stores them); `None` when the offsets are not ascending from 0 or run
    /// past the entries.
    pub fn from_rows(offsets: &[u32], nodes: Vec<u32>, visibility: Vec<u16>) -> Option<Self> {
        let end = *offsets.last()? as usize;
        if offsets[0] != 0
            || offsets.windows(2).any(|w| w[0] > w[1])
            || end != nodes.len()
            || end != visibility.len()
        {
            return None;
        }
        Some(Self {
            spans: offsets.windows(2).map(|w| [w[0], w[1]]).collect(),
            nodes,
            visibility,
        })
    }

    /// Vertex v's cut becomes `entries` ((node, V) in pre-order), appended to the storage (a
    /// vertex set twice keeps the space of its first cut). Vertices past the end are added.
    ///
    /// # Panics
    /// When the storage passes 2³² entries (the file's offsets are u32).
    pub fn set(&mut self, v: usize, entries: &[(u32, f32)]) {
        if v >= self.spans.len() {
            self.spans.resize(v + 1, [0, 0]);
        }
        let first = self.nodes.len();
        self.nodes.extend(entries.iter().map(|e| e.0));
        self.visibility
            .extend(entries.iter().map(|e| quantise(e.1)));
        // Fires only past 2³² nodes (~25 GB of cuts), which no bake holds in memory and the
        // file's u32 offsets could not store.
        let end = u32::try_from(self.nodes.len()).expect("more than 2^32 cut nodes");
        self.spans[v] = [first as u32, end];
    }

    /// [`Cuts::set`] for many vertices at once, `entries[i]` becoming vertex `vertices[i]`'s cut,
    /// appended in that order (the same storage as setting them one by one); the entries are
    /// copied and quantised in parallel, so that a bake's store of a batch does not hold up the
    /// other threads.
    ///
    /// # Panics
    /// When the storage passes 2³² entries (as [`Cuts::set`]), or the two lengths differ.
    pub fn set_many(&mut self, vertices: &[usize], entries: &[&[(u32, f32)]]) {
        assert_eq!(vertices.len(), entries.len(), "a cut per vertex");
        if let Some(&last) = vertices.iter().max()
            && last >= self.spans.len()
        {
            self.spans.resize(last + 1, [0, 0]);
        }
        let base = self.nodes.len();
        let end = base + entries.iter().map(|e| e.len()).sum::<usize>();
        // Fires only past 2³² nodes, as in `set`.
        u32::try_from(end).expect("more than 2^32 cut nodes");
        self.nodes.resize(end, 0);
        self.visibility.resize(end, 0);
        let mut slices = Vec::with_capacity(entries.len());
        let (mut nodes, mut visibility) = (&mut self.nodes[base..], &mut self.visibility[base..]);
        let mut first = base;
        for (&v, e) in vertices.iter().zip(entries) {
            let (n, rest_n) = std::mem::take(&mut nodes).split_at_mut(e.len());
            let (q, rest_q) = std::mem::take(&mut visibility).split_at_mut(e.len());
            (nodes, visibility) = (rest_n, rest_q);
            slices.push((n, q, *e));
            self.spans[v] = [first as u32, (first + e.len()) as u32];
            first += e.len();
        }
        use rayon::prelude::*;
        slices
            .into_par_iter()
            .with_min_len(256)
            .for_each(|(n, q, e)| {
                for ((n, q), &(k, v)) in n.iter_mut().zip(q.iter_mut()).zip(e) {
                    *n = k;
                    *q = quantise(v);
                }
            });
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.spans.len()
    }

    fn range(&self, v: usize) -> std::ops::Range<usize> {
        self.spans
            .get(v)
            .map_or(0..0, |&[a, b]| a as usize..b as usize)
    }

    /// The light-tree nodes of vertex v's cut, in pre-order.
    pub fn nodes_of(&self, v: usize) -> &[u32] {
        &self.nodes[self.range(v)]
    }

    /// V of vertex v's cut nodes, quantised (V = q / 65535).
    pub fn quantised(&self, v: usize) -> &[u16] {
        &self.visibility[self.range(v)]
    }

    /// Number of nodes in vertex v's cut.
    pub fn cut_len(&self, v: usize) -> usize {
        self.range(v).len()
    }

    /// (node, V) of vertex v's cut.
    pub fn cut(&self, v: usize) -> impl Iterator<Item = (u32, f32)> + '_ {
        let range = self.range(v);
        self.nodes[range.clone()]
            .iter()
            .zip(&self.visibility[range])
            .map(|(&n, &q)| (n, q as f32 / 65535.0))
    }

    /// Vertex v's cut into `out` (cleared first): for the steps that read a stored cut back.
    pub fn cut_into(&self, v: usize, out: &mut Vec<(u32, f32)>) {
        out.clear();
        out.extend(self.cut(v));
    }

    /// Total number of cut nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Mean number of nodes per vertex.
    pub fn mean_cut_size(&self) -> f64 {
        self.nodes.len() as f64 / self.vertex_count().max(1) as f64
    }

    /// Bytes of the cut storage.
    pub fn bytes(&self) -> usize {
        self.spans.len() * 8 + self.nodes.len() * 4 + self.visibility.len() * 2
    }

    /// Drops spare capacity (the storage grows by doubling while a bake runs).
    pub fn shrink_to_fit(&mut self) {
        self.nodes.shrink_to_fit();
        self.visibility.shrink_to_fit();
    }
}

fn quantise(v: f32) -> u16 {
    (v.clamp(0.0, 1.0) * 65535.0).round() as u16
}

/// What a bake in progress knows per vertex beside its cut.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct VertexRecord {
    /// Rays cast for the vertex.
    pub rays: u64,
    /// ε actually used (above the settings' where the cut's cap relaxed it).
    pub epsilon_used: f64,
    /// Interpolated from sampled neighbours instead of traced.
    pub interpolated: bool,
}

/// When a stage started and the rays cast by then ([`PartialBake::start_stage`]).
#[derive(Debug, Clone, Copy)]
pub struct StageStart {
    at: std::time::Instant,
    rays: u64,
}

/// The cuts of a bake in progress ([`super::Baker::bake_set`], [`super::Baker::refine`]): packed
/// cuts, which vertices are baked, and per vertex its [`VertexRecord`].
#[derive(Debug, Clone, Default)]
pub struct PartialBake {
    pub cuts: Cuts,
    pub baked: Vec<bool>,
    pub records: Vec<VertexRecord>,
    /// Sampled vertices' [`VertexCut::cell_bits`], kept for the vertices that take their agreed
    /// cells, in this [`super::Baker::bake_set`] call or a later one; dropped by the refinement.
    pub(super) cell_bits: Vec<Vec<[u64; 2]>>,
    /// [`super::BakeStats::stages`] so far.
    pub stages: Vec<super::BakeStage>,
}

impl PartialBake {
    /// `vertex_count` vertices, none baked.
    pub fn new(vertex_count: usize) -> Self {
        Self {
            cuts: Cuts::with_vertices(vertex_count),
            baked: vec![false; vertex_count],
            records: vec![VertexRecord::default(); vertex_count],
            cell_bits: Vec::new(),
            stages: Vec::new(),
        }
    }

    /// Rays cast for the vertices baked so far.
    pub fn rays(&self) -> u64 {
        self.records.iter().map(|r| r.rays).sum()
    }

    /// Starts timing a stage ([`PartialBake::end_stage`]).
    pub fn start_stage(&self) -> StageStart {
        StageStart {
            at: std::time::Instant::now(),
            rays: self.rays(),
        }
    }

    /// Adds to stage `name` (a stage met before in this bake adds to it) `vertices` finished, the
    /// rays cast and the seconds since `start`.
    pub fn end_stage(&mut self, name: &str, vertices: usize, start: StageStart) {
        let (rays, seconds) = (
            self.rays().saturating_sub(start.rays),
            start.at.elapsed().as_secs_f64(),
        );
        match self.stages.iter_mut().find(|s| s.stage == name) {
            Some(s) => {
                s.vertices += vertices;
                s.rays += rays;
                s.seconds += seconds;
            }
            None => self.stages.push(super::BakeStage {
                stage: name.to_string(),
                vertices,
                rays,
                seconds,
            }),
        }
    }

    /// Number of vertices (baked or not).
    pub fn vertex_count(&self) -> usize {
        self.baked.len()
    }

    /// Stores vertex v's cut (vertices past the end are added) and marks it baked; its cell bits
    /// are kept when it recorded any.
    pub fn store(&mut self, v: usize, cut: VertexCut) {
        self.store_many(&[v], vec![cut]);
    }

    /// Stores cut i as vertex `vertices[i]`'s ([`PartialBake::store`]), in the same storage as
    /// storing them one by one in that order; the cuts are packed, and their unpacked form
    /// dropped, in parallel ([`Cuts::set_many`]).
    pub fn store_many(&mut self, vertices: &[usize], cuts: Vec<VertexCut>) {
        use rayon::prelude::*;
        if let Some(&last) = vertices.iter().max()
            && last >= self.baked.len()
        {
            self.baked.resize(last + 1, false);
            self.records.resize(last + 1, VertexRecord::default());
        }
        {
            let entries: Vec<&[(u32, f32)]> = cuts.iter().map(|c| c.entries.as_slice()).collect();
            self.cuts.set_many(vertices, &entries);
        }
        let kept: Vec<(VertexRecord, Vec<[u64; 2]>)> = cuts
            .into_par_iter()
            .with_min_len(256)
            .map(|c| {
                let record = VertexRecord {
                    rays: c.rays,
                    epsilon_used: c.epsilon_used,
                    interpolated: c.interpolated,
                };
                (record, c.cell_bits)
            })
            .collect();
        for (&v, (record, bits)) in vertices.iter().zip(kept) {
            self.baked[v] = true;
            self.records[v] = record;
            if !bits.is_empty() {
                if self.cell_bits.len() <= v {
                    self.cell_bits.resize(v + 1, Vec::new());
                }
                self.cell_bits[v] = bits;
            }
        }
    }

    /// Vertex v's cut as stored (quantised V; no cell bits).
    pub fn vertex(&self, v: usize) -> VertexCut {
        let record = self.records.get(v).copied().unwrap_or_default();
        VertexCut {
            entries: self.cuts.cut(v).collect(),
            rays: record.rays,
            epsilon_used: record.epsilon_used,
            interpolated: record.interpolated,
            cell_bits: Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cut(entries: &[(u32, f32)]) -> VertexCut {
        VertexCut {
            entries: entries.to_vec(),
            ..VertexCut::default()
        }
    }

    #[test]
    fn cuts_stored_out_of_order_equal_those_packed_in_order() {
        let all = [
            cut(&[(1, 1.0), (2, 0.0)]),
            cut(&[]),
            cut(&[(0, 0.5)]),
            cut(&[(3, 0.0), (4, 1.0), (5, 0.75)]),
        ];
        let in_order = Cuts::from_vertex_cuts(&all);
        let mut partial = PartialBake::new(all.len());
        for v in [3, 0, 2, 1] {
            partial.store(v, all[v].clone());
        }
        assert_eq!(partial.cuts, in_order);
        assert_eq!(
            in_order.cut(3).collect::<Vec<_>>(),
            partial.vertex(3).entries
        );
        // 0 and 1 are exact in 16 bits; V in between comes back within 7.6e-6.
        assert_eq!(partial.vertex(0).entries, vec![(1, 1.0), (2, 0.0)]);
        let (_, v) = partial.vertex(3).entries[2];
        assert!((v - 0.75).abs() <= 7.7e-6, "{v}");
        assert_eq!(in_order.cut_len(3), 3);
        assert_eq!(in_order.node_count(), 6);
        // Rows as a file stores them give the same cuts; bad rows are refused.
        let rows = Cuts::from_rows(&[0, 2, 2, 3, 6], in_order.nodes.clone(), {
            in_order.visibility.clone()
        });
        assert_eq!(rows.as_ref(), Some(&in_order));
        assert!(Cuts::from_rows(&[0, 3, 2], vec![0; 3], vec![0; 3]).is_none());
        assert!(Cuts::from_rows(&[1, 3], vec![0; 3], vec![0; 3]).is_none());
        assert!(Cuts::from_rows(&[0, 4], vec![0; 3], vec![0; 3]).is_none());
        // A different V is a different cut.
        partial.store(2, cut(&[(0, 0.6)]));
        assert_ne!(partial.cuts, in_order);
    }

    /// Storing a batch at once lays the storage out as storing its cuts one by one, in order:
    /// the same spans, nodes and quantised V byte for byte, records and cell bits, with vertices
    /// out of order, past the end and stored twice.
    #[test]
    fn a_batch_stored_at_once_is_stored_as_one_by_one() {
        let mut rng = crate::math::Rng::new(5);
        let batches: Vec<Vec<(usize, VertexCut)>> = (0..3)
            .map(|b| {
                (0..700)
                    .map(|i| {
                        let len = (rng.next_f64() * 9.0) as usize;
                        let entries = (0..len)
                            .map(|j| (j as u32 * 3 + i as u32, rng.next_f64() as f32))
                            .collect();
                        let v = (i * 37 + b * 11) % 1000;
                        let cell_bits = if i % 3 == 0 {
                            vec![[i as u64, b as u64]]
                        } else {
                            Vec::new()
                        };
                        (
                            v,
                            VertexCut {
                                entries,
                                rays: i as u64,
                                epsilon_used: 0.02 + b as f64,
                                interpolated: i % 2 == 0,
                                cell_bits,
                            },
                        )
                    })
                    .collect()
            })
            .collect();
        // The reference: each cut set on its own (`Cuts::set`), its record and bits written out.
        let mut cuts = Cuts::with_vertices(900);
        let (mut baked, mut records) = (vec![false; 1000], vec![VertexRecord::default(); 1000]);
        let mut cell_bits = vec![Vec::new(); 1000];
        let mut many = PartialBake::new(900);
        for batch in &batches {
            for (v, c) in batch {
                cuts.set(*v, &c.entries);
                baked[*v] = true;
                records[*v] = VertexRecord {
                    rays: c.rays,
                    epsilon_used: c.epsilon_used,
                    interpolated: c.interpolated,
                };
                if !c.cell_bits.is_empty() {
                    cell_bits[*v] = c.cell_bits.clone();
                }
            }
            let (ids, batch_cuts): (Vec<usize>, Vec<VertexCut>) = batch.iter().cloned().unzip();
            many.store_many(&ids, batch_cuts);
        }
        assert_eq!(cuts.spans, many.cuts.spans);
        assert_eq!(cuts.nodes, many.cuts.nodes);
        assert_eq!(cuts.visibility, many.cuts.visibility);
        let end = many.baked.len();
        assert!(end > 900);
        assert_eq!(baked[..end], many.baked[..]);
        assert_eq!(records[..end], many.records[..]);
        let last_bits = cell_bits.iter().rposition(|b| !b.is_empty()).unwrap_or(0);
        assert_eq!(cell_bits[..=last_bits], many.cell_bits[..]);
    }
}
