// prt_shade.wgsl — the per-vertex PRT sum of eq. 22 (method.md §7), one workgroup per mesh vertex.
//
// BRDF convention (stated once in src/brdf/mod.rs, repeated here): f_r(wi, wo) = ρd/π + p(h)·s(wi, wo)
// WITHOUT the cosine; local frame z = normal, x = tangent; s = F_schlick(wi·h) / (4·(k1 + k2·(1 − k1))),
// k1 = wi·n, k2 = wo·n; G(x; λ) = exp(2λ(x − 1)), tabulated as p(h) on the hemi-octahedral map.
//
// B(v, wo) = Σ_runs V_run · P_run · (ρd/π + p̃(h_run) s(ω_run, wo)): the vertex's cut (leaf ranges
// with V) walked together with the render partition, exactly as `bake::runs::for_each_run` does with
// one list and `render::prt::Prt::shade_point` does per run. Every run is one light-tree node (cut and
// partition nodes are nested or disjoint), so its light is read per node from `light`.
// Per lane a bisection and one flat loop, no nested ones: llvmpipe's 65,535-iteration budget is
// shared by all loops (`shade_block`).
//
// Must match: the Rust mirrors in src/gpu/uniforms.rs (ShadeUniforms, GpuVertex, CutEntry,
// PartitionEntry, GpuLeaf, NodeLight) and the CPU reference src/render/prt.rs.

struct ShadeUniforms {
    eye: vec4<f32>,            // xyz: eye in world space
    rho_d_f0: vec4<f32>,       // rgb: ρd, w: F0
    counts: vec4<u32>,         // vertex_count, leaf_count, partition_count, node_count
    table: vec4<u32>,          // level_count, flags (FLAG_*), bitcast<u32>(λ), 0
    levels: array<vec4<u32>, 40>, // per level: texel offset into `table`, resolution, 0, 0
}

struct GpuVertex {
    position: vec4<f32>,       // xyz world, w 1
    normal: vec4<f32>,         // xyz unit world normal
    tangent: vec4<f32>,        // xyz world tangent, w handedness ±1 (used only with FLAG_TANGENTS)
}

struct PartitionEntry {
    range: vec4<u32>,          // first leaf, end leaf, light-tree node, 0
    cone: vec4<f32>,           // axis xyz, cos of the half-angle bounding every leaf corner
}

struct GpuLeaf {
    c0: vec4<f32>,             // the texel's four corners (unit vectors)
    c1: vec4<f32>,
    c2: vec4<f32>,
    c3: vec4<f32>,
    moment: vec4<f32>,         // ∫ ω dω over the texel
}

const FLAG_SPECULAR: u32 = 1u;
const FLAG_PREFILTER: u32 = 2u;
const FLAG_TANGENTS: u32 = 4u;
const LEVEL_STEP_OCTAVES: f32 = 0.5;
const DENOMINATOR_FLOOR: f32 = 1e-12;
const LUMINANCE: vec3<f32> = vec3<f32>(0.2126, 0.7152, 0.0722);
const INV_PI: f32 = 0.31830988618379067;
// Invocations per vertex (the workgroup size).
const LANES: u32 = 64u;

@group(0) @binding(0) var<uniform> u: ShadeUniforms;
@group(0) @binding(1) var<storage, read> vertices: array<GpuVertex>;
// Per vertex v its cut entries are cut_entries[cut_offsets[v] .. cut_offsets[v + 1]].
@group(0) @binding(2) var<storage, read> cut_offsets: array<u32>;
// (first leaf, end leaf, bitcast<u32>(V), light-tree node), in leaf order.
@group(0) @binding(3) var<storage, read> cut_entries: array<vec4<u32>>;
@group(0) @binding(4) var<storage, read> render_partition: array<PartitionEntry>;
@group(0) @binding(5) var<storage, read> leaves: array<GpuLeaf>;
// Node k: light[3k + c] = (radiance-weighted moment of channel c (xyz), power of channel c (w));
// then leaf i's radiance at light[3·node_count + i].
@group(0) @binding(6) var<storage, read> light: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> table: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read_write> radiance: array<vec4<f32>>;

struct Frame {
    t: vec3<f32>,
    b: vec3<f32>,
    n: vec3<f32>,
}

// Duff et al.'s branchless basis (as sphere::Frame::from_normal).
fn frame_from_normal(n: vec3<f32>) -> Frame {
    let sign = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    return Frame(vec3<f32>(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), vec3<f32>(b, sign + n.y * n.y * a, -n.y), n);
}

// As sphere::Frame::from_normal_tangent: Gram-Schmidt, handedness, fallback for a degenerate tangent.
fn frame_from_normal_tangent(n: vec3<f32>, tangent: vec3<f32>, handedness: f32) -> Frame {
    let t = tangent - n * dot(n, tangent);
    let len = length(t);
    if !(len > 1e-8) {
        return frame_from_normal(n);
    }
    let tn = t / len;
    let w = select(1.0, -1.0, handedness < 0.0);
    return Frame(tn, cross(n, tn) * w, n);
}

fn to_local(f: Frame, v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(v, f.t), dot(v, f.b), dot(v, f.n));
}

fn leaf_wholly_above(leaf: GpuLeaf, n: vec3<f32>) -> bool {
    return dot(leaf.c0.xyz, n) >= 0.0 && dot(leaf.c1.xyz, n) >= 0.0 && dot(leaf.c2.xyz, n) >= 0.0 && dot(leaf.c3.xyz, n) >= 0.0;
}

// Arvo's term of one great-circle edge a→b: θ n̂ (the arc by atan2, exact for short edges in f32).
fn edge_moment(a: vec3<f32>, b: vec3<f32>) -> vec3<f32> {
    let c = cross(a, b);
    let cl = length(c);
    if !(cl > 0.0) {
        return vec3<f32>(0.0);
    }
    return (c / cl) * atan2(cl, dot(a, b));
}

// The point of the arc a→b on the plane ω·n = 0 (ha = a·n, hb = b·n of opposite signs).
fn horizon_point(a: vec3<f32>, b: vec3<f32>, ha: f32, hb: f32) -> vec3<f32> {
    let q = a * hb - b * ha;
    let p = q / max(length(q), 1e-30);
    return select(p, -p, dot(p, a + b) < 0.0);
}

// ∫ max(ω·n, 0) dω over a texel cut by the horizon: the texel clipped to it (a spherical polygon with
// great-circle edges, since the horizon is a great circle) and its moment by Arvo's formula
// ½ Σ θ_e n̂_e, dotted with n (sphere::direction_set::clipped_cosine_integral). The clipped polygon is
// walked edge by edge without being stored: the part of each texel edge above the horizon, then the
// horizon arc from where the boundary leaves the hemisphere to where it comes back. (A first version
// stored the polygon in a dynamically indexed local array; on lavapipe that dropped leaves from the sum,
// 8 % in the white furnace test of tests/it/gpu.rs.)
fn clipped_cosine_integral(leaf: GpuLeaf, n: vec3<f32>) -> f32 {
    // The four edges by calls, not a loop: every loop iteration counts against lavapipe's budget (see
    // `shade`).
    var c = ClipWalk(vec3<f32>(0.0), vec3<f32>(0.0), 0u, vec3<f32>(0.0), vec3<f32>(0.0), 0u);
    c = clip_edge(c, leaf.c0.xyz, leaf.c1.xyz, n);
    c = clip_edge(c, leaf.c1.xyz, leaf.c2.xyz, n);
    c = clip_edge(c, leaf.c2.xyz, leaf.c3.xyz, n);
    c = clip_edge(c, leaf.c3.xyz, leaf.c0.xyz, n);
    if c.corners_above == 0u || c.corners_above + c.crossings < 3u {
        return 0.0;
    }
    var m = c.m;
    if c.crossings == 2u {
        m += edge_moment(c.exit_point, c.entry_point);
    }
    m *= 0.5;
    if dot(m, c.inside) < 0.0 {
        m = -m;
    }
    return max(dot(m, n), 0.0);
}

// The state of the walk around a clipped texel: the moment so far, a point inside (the sum of the
// clipped polygon's vertices, for the orientation), and where the boundary leaves and re-enters the
// upper hemisphere.
struct ClipWalk {
    m: vec3<f32>,
    inside: vec3<f32>,
    corners_above: u32,
    exit_point: vec3<f32>,
    entry_point: vec3<f32>,
    crossings: u32,
}

// One texel edge a→b: the part of it above the horizon.
fn clip_edge(walk: ClipWalk, a: vec3<f32>, b: vec3<f32>, n: vec3<f32>) -> ClipWalk {
    var c = walk;
    let ha = dot(a, n);
    let hb = dot(b, n);
    if ha >= 0.0 {
        c.inside += a;
        c.corners_above++;
        if hb >= 0.0 {
            c.m += edge_moment(a, b);
        } else {
            let p = horizon_point(a, b, ha, hb);
            c.m += edge_moment(a, p);
            c.exit_point = p;
            c.inside += p;
            c.crossings++;
        }
    } else if hb >= 0.0 {
        let p = horizon_point(a, b, ha, hb);
        c.m += edge_moment(p, b);
        c.entry_point = p;
        c.inside += p;
        c.crossings++;
    }
    return c;
}

// ∫ max(ω·n, 0) dω over leaf i: its moment when wholly above the horizon, else the clipped texel.
fn leaf_cosine_integral(i: u32, n: vec3<f32>) -> f32 {
    let leaf = leaves[i];
    if leaf_wholly_above(leaf, n) {
        return dot(leaf.moment.xyz, n);
    }
    return clipped_cosine_integral(leaf, n);
}

fn schlick(f0: f32, c: f32) -> f32 {
    let m = 1.0 - clamp(c, 0.0, 1.0);
    let m2 = m * m;
    return f0 + (1.0 - f0) * m2 * m2 * m;
}

// s(wi, wo) given h (brdf::dbrdf::static_term).
fn static_term(wi: vec3<f32>, wo: vec3<f32>, h: vec3<f32>, f0: f32) -> f32 {
    let k1 = wi.z;
    let k2 = wo.z;
    if !(k1 > 0.0 && k2 > 0.0) {
        return 0.0;
    }
    let c1 = clamp(k1, 0.0, 1.0);
    let c2 = clamp(k2, 0.0, 1.0);
    let d = max(c1 + c2 * (1.0 - c1), DENOMINATOR_FLOOR);
    return schlick(f0, dot(wi, h)) / (4.0 * d);
}

// Hemi-octahedral (u, v) of a local unit vector: must match glint_exporters::hemi_oct_encode (the one
// definition; tests/it/gpu.rs runs this copy against it on every texel, below the horizon too).
fn hemi_oct_encode(h: vec3<f32>) -> vec2<f32> {
    let l1 = abs(h.x) + abs(h.y) + abs(h.z);
    if !(l1 > 0.0) {
        return vec2<f32>(0.5, 0.5);
    }
    let px = h.x / l1;
    let py = h.y / l1;
    return vec2<f32>((px + py + 1.0) * 0.5, (px - py + 1.0) * 0.5);
}

// Bilinear on a corner-aligned R×R level (render::table::bilinear).
fn table_bilinear(level: u32, h: vec3<f32>) -> vec3<f32> {
    let info = u.levels[level];
    let offset = info.x;
    let r = info.y;
    let rm = f32(r - 1u);
    let uv = hemi_oct_encode(h);
    let x = clamp(uv.x * rm, 0.0, rm);
    let y = clamp(uv.y * rm, 0.0, rm);
    let x0 = u32(x);
    let y0 = u32(y);
    let x1 = min(x0 + 1u, r - 1u);
    let y1 = min(y0 + 1u, r - 1u);
    let fx = x - f32(x0);
    let fy = y - f32(y0);
    let a = table[offset + y0 * r + x0].xyz;
    let b = table[offset + y0 * r + x1].xyz;
    let c = table[offset + y1 * r + x0].xyz;
    let d = table[offset + y1 * r + x1].xyz;
    let top = a + (b - a) * fx;
    let bottom = c + (d - c) * fx;
    return top + (bottom - top) * fy;
}

// p̃(h) under an angular spread (rad², half-vector space): linear between the two pre-filtered
// levels around 2·log2(1 + 2λ·spread) (render::table::PhTable::lookup_filtered).
fn table_lookup(h: vec3<f32>, spread: f32) -> vec3<f32> {
    let level_count = u.table.x;
    let lambda = bitcast<f32>(u.table.z);
    var t = 0.0;
    if spread > 0.0 {
        t = log2(1.0 + 2.0 * lambda * spread) / LEVEL_STEP_OCTAVES;
    }
    t = min(t, f32(level_count - 1u));
    let i = u32(t);
    let f = t - f32(i);
    let a = table_bilinear(i, h);
    if f <= 0.0 || i + 1u >= level_count {
        return a;
    }
    let b = table_bilinear(i + 1u, h);
    return a + (b - a) * f;
}

// Node k's light: per channel its radiance-weighted moment (xyz) and power (w).
struct NodeMoments {
    r: vec4<f32>,
    g: vec4<f32>,
    b: vec4<f32>,
}

fn node_moments(k: u32) -> NodeMoments {
    return NodeMoments(light[3u * k], light[3u * k + 1u], light[3u * k + 2u]);
}

// What one run adds.
struct RunShade {
    e: vec3<f32>,
    spec: vec3<f32>,
}

// A run of light-tree node `node`, visibility `vis`, with ∫ L max(ω·n, 0) dω = `cos_power` per channel:
// its share of the irradiance and, lit from its light's luminance-weighted direction, its specular
// radiance.
fn shade_run(node: u32, vis: f32, cos_power: vec3<f32>, n: vec3<f32>, frame: Frame, wo: vec3<f32>, specular_on: bool, prefilter: bool, f0: f32) -> RunShade {
    var result = RunShade(vec3<f32>(0.0), vec3<f32>(0.0));
    if all(cos_power <= vec3<f32>(0.0)) {
        return result;
    }
    result.e = vis * cos_power;
    if !specular_on {
        return result;
    }
    let m = node_moments(node);
    let lum_moment = m.r.xyz * LUMINANCE.x + m.g.xyz * LUMINANCE.y + m.b.xyz * LUMINANCE.z;
    let lum_len = length(lum_moment);
    if !(lum_len > 0.0) {
        return result;
    }
    let wi = to_local(frame, lum_moment / lum_len);
    if wi.z <= 0.0 {
        return result;
    }
    let hs = wi + wo;
    let hl = length(hs);
    if !(hl > 0.0) {
        return result;
    }
    let h = hs / hl;
    let s = static_term(wi, wo, h, f0);
    if s <= 0.0 {
        return result;
    }
    var spread = 0.0;
    if prefilter {
        let lum_power = dot(vec3<f32>(m.r.w, m.g.w, m.b.w), LUMINANCE);
        if lum_power > 0.0 {
            spread = max(1.0 - lum_len / lum_power, 0.0) / (4.0 * max(dot(wo, h), 1e-3));
        }
    }
    result.spec = vis * cos_power * s * table_lookup(h, spread);
    return result;
}

// A vertex's lanes: each sums the runs of its share of the partition nodes, then the lanes add up.
var<workgroup> lane_e: array<vec4<f32>, LANES>;
var<workgroup> lane_spec: array<vec4<f32>, LANES>;

// One workgroup per vertex (the grid is 2D past 65,535 vertices: v = x + y · groups in x). Lane l walks
// the partition nodes l, l + LANES, l + 2·LANES, …: the runs are cut at partition boundaries anyway, so
// the lanes' runs are the whole walk's runs. A vertex's walk is a few thousand dependent steps (its
// runs and the leaves astride its horizon); spread over the lanes, a frame does not wait for the
// longest walk done alone. Every LANES-th node rather than a contiguous block per lane, because the
// nodes astride the horizon lie together in leaf order and a block would give them to a few lanes
// (docs/benchmarks.md, "The wgpu preview").
@compute @workgroup_size(64)
fn shade(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    let v = group.x + group.y * groups.x;
    var e = vec3<f32>(0.0);
    var spec = vec3<f32>(0.0);
    var lit = false;
    if v < u.counts.x {
        let vertex = vertices[v];
        let n_len = length(vertex.normal.xyz);
        if n_len > 0.0 {
            lit = true;
            let r = shade_block(vertex, vertex.normal.xyz / n_len, v, lane);
            e = r.e;
            spec = r.spec;
        }
    }
    lane_e[lane] = vec4<f32>(e, 0.0);
    lane_spec[lane] = vec4<f32>(spec, 0.0);
    workgroupBarrier();
    for (var stride = LANES / 2u; stride > 0u; stride = stride / 2u) {
        if lane < stride {
            lane_e[lane] += lane_e[lane + stride];
            lane_spec[lane] += lane_spec[lane + stride];
        }
        workgroupBarrier();
    }
    if lane == 0u && v < u.counts.x {
        var out = vec4<f32>(0.0, 0.0, 0.0, 1.0);
        if lit {
            out = vec4<f32>(u.rho_d_f0.xyz * INV_PI * lane_e[0].xyz + lane_spec[0].xyz, 1.0);
        }
        radiance[v] = out;
    }
}

// What lane `lane` of vertex `v` (unit normal `n`) adds: the irradiance (e) and specular radiance of the
// runs inside its partition nodes, every LANES-th from the lane's index.
fn shade_block(vertex: GpuVertex, n: vec3<f32>, v: u32, lane: u32) -> RunShade {
    var result = RunShade(vec3<f32>(0.0), vec3<f32>(0.0));
    let partition_count = u.counts.z;
    let flags = u.table.y;
    var frame: Frame;
    if (flags & FLAG_TANGENTS) != 0u {
        frame = frame_from_normal_tangent(n, vertex.tangent.xyz, vertex.tangent.w);
    } else {
        frame = frame_from_normal(n);
    }
    let to_eye = u.eye.xyz - vertex.position.xyz;
    let eye_len = length(to_eye);
    var wo_world = n;
    if eye_len > 0.0 {
        wo_world = to_eye / eye_len;
    }
    let wo = to_local(frame, wo_world);
    // The silhouette rule: where the normal faces away from the eye only the diffuse term remains.
    let specular_on = (flags & FLAG_SPECULAR) != 0u && wo.z > 0.0;
    let prefilter = (flags & FLAG_PREFILTER) != 0u;
    let f0 = u.rho_d_f0.w;
    let leaf_light = 3u * u.counts.w;

    // The partition node being walked (si; its leaves [pos, node_end)), whether it lies wholly above
    // the horizon, and the cut cursor idx: the first cut entry that ends after pos, found by bisection
    // over [idx, hi) when a node is taken.
    var si = lane;
    var taken = false;
    var part = PartitionEntry(vec4<u32>(0u), vec4<f32>(0.0));
    var above = false;
    var pos = 0u;
    var node_end = 0u;
    var idx = cut_offsets[v];
    var hi = idx;
    let idx_end = cut_offsets[v + 1u];
    // A run astride the horizon, summed one leaf per iteration: leaves [leaf, run_end) still to go.
    var leaf = 0u;
    var run_end = 0u;
    var run_node = 0u;
    var run_vis = 0.0;
    var run_cos = vec3<f32>(0.0);
    // One flat loop whose every iteration sums one leaf of a run astride the horizon, or takes one
    // bisection step, or takes the lane's next partition node, or takes the next run: lavapipe
    // (llvmpipe) ends a shader's loops after 65,535 iterations in all (LP_MAX_TGSI_LOOP_ITERATIONS,
    // shared by every loop and counted per SIMD group of 8 invocations), so nested loops, whose
    // iterations add up over the group's union of horizon nodes, lost runs at 8° partitions (the white
    // furnace 0.55 off). Here a group takes as many iterations as its busiest invocation.
    loop {
        if leaf < run_end {
            let ci = leaf_cosine_integral(leaf, n);
            if ci > 0.0 {
                run_cos += light[leaf_light + leaf].xyz * ci;
            }
            leaf++;
            if leaf == run_end {
                let r = shade_run(run_node, run_vis, run_cos, n, frame, wo, specular_on, prefilter, f0);
                result.e += r.e;
                result.spec += r.spec;
            }
            continue;
        }
        if idx < hi {
            let mid = (idx + hi) / 2u;
            if cut_entries[mid].y <= pos {
                idx = mid + 1u;
            } else {
                hi = mid;
            }
            continue;
        }
        if pos >= node_end {
            if taken {
                si += LANES;
            }
            taken = true;
            if si >= partition_count {
                break;
            }
            part = render_partition[si];
            // A partition node wholly below the horizon contributes nothing; one wholly above is
            // its runs' light moments · n; one astride it is summed leaf by leaf (the exact clip
            // where cut).
            let axis = part.cone.xyz;
            let ccos = part.cone.w;
            let csin = sqrt(max(1.0 - ccos * ccos, 0.0));
            let cb = dot(axis, n);
            let sb = sqrt(max(1.0 - cb * cb, 0.0));
            if cb < 0.0 && cb * ccos + sb * csin <= 0.0 {
                continue;
            }
            above = cb * ccos - sb * csin > 0.0 && sb * ccos + cb * csin > 0.0;
            pos = part.range.x;
            node_end = part.range.y;
            hi = idx_end;
            continue;
        }
        var next = node_end;
        var vis = 0.0;
        var node = part.range.z;
        // Runs end at cut boundaries, so each step passes at most one cut entry.
        if idx < idx_end && cut_entries[idx].y <= pos {
            idx++;
        }
        if idx < idx_end {
            let sp = cut_entries[idx];
            if sp.x <= pos {
                vis = bitcast<f32>(sp.z);
                next = min(next, sp.y);
                // The run is the smaller of the two nested nodes.
                if sp.y - sp.x < part.range.y - part.range.x {
                    node = sp.w;
                }
            } else {
                next = min(next, sp.x);
            }
        }
        let a = pos;
        let z = next;
        pos = next;
        if !(vis > 0.0) {
            continue;
        }
        if above {
            let m = node_moments(node);
            let cos_power = max(vec3<f32>(dot(m.r.xyz, n), dot(m.g.xyz, n), dot(m.b.xyz, n)), vec3<f32>(0.0));
            let r = shade_run(node, vis, cos_power, n, frame, wo, specular_on, prefilter, f0);
            result.e += r.e;
            result.spec += r.spec;
        } else {
            leaf = a;
            run_end = z;
            run_node = node;
            run_vis = vis;
            run_cos = vec3<f32>(0.0);
        }
    }
    return result;
}
