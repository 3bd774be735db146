// prt_shade.wgsl — the per-vertex PRT sum of eq. 22 (method.md §7), one invocation per mesh vertex.
//
// BRDF convention (stated once in src/brdf/mod.rs, repeated here): f_r(wi, wo) = ρd/π + p(h)·s(wi, wo)
// WITHOUT the cosine; local frame z = normal, x = tangent; s = F_schlick(wi·h) / (4·(k1 + k2·(1 − k1))),
// k1 = wi·n, k2 = wo·n; G(x; λ) = exp(2λ(x − 1)), tabulated as p(h) on the hemi-octahedral map.
//
// B(v, wo) = Σ_runs V_run · P_run · (ρd/π + p̃(h_run) s(ω_run, wo)): the vertex's cut (leaf ranges
// with V) walked together with the render partition, exactly as `bake::runs::for_each_run` does with
// one list and `render::prt::Prt::shade_point` does per run. Every run is one light-tree node (cut and
// partition nodes are nested or disjoint), so its light is read per node from `light`.
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

fn leaf_corner(leaf: GpuLeaf, k: u32) -> vec3<f32> {
    switch k {
        case 0u: { return leaf.c0.xyz; }
        case 1u: { return leaf.c1.xyz; }
        case 2u: { return leaf.c2.xyz; }
        default: { return leaf.c3.xyz; }
    }
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
// 8 % in the white furnace test of tests/gpu.rs.)
fn clipped_cosine_integral(leaf: GpuLeaf, n: vec3<f32>) -> f32 {
    var m = vec3<f32>(0.0);
    var inside = vec3<f32>(0.0);
    var corners_above = 0u;
    var exit_point = vec3<f32>(0.0);
    var entry_point = vec3<f32>(0.0);
    var crossings = 0u;
    for (var k = 0u; k < 4u; k++) {
        let a = leaf_corner(leaf, k);
        let b = leaf_corner(leaf, (k + 1u) % 4u);
        let ha = dot(a, n);
        let hb = dot(b, n);
        if ha >= 0.0 {
            inside += a;
            corners_above++;
            if hb >= 0.0 {
                m += edge_moment(a, b);
            } else {
                let p = horizon_point(a, b, ha, hb);
                m += edge_moment(a, p);
                exit_point = p;
                inside += p;
                crossings++;
            }
        } else if hb >= 0.0 {
            let p = horizon_point(a, b, ha, hb);
            m += edge_moment(p, b);
            entry_point = p;
            inside += p;
            crossings++;
        }
    }
    if corners_above == 0u || corners_above + crossings < 3u {
        return 0.0;
    }
    if crossings == 2u {
        m += edge_moment(exit_point, entry_point);
    }
    m *= 0.5;
    if dot(m, inside) < 0.0 {
        m = -m;
    }
    return max(dot(m, n), 0.0);
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

// Hemi-octahedral (u, v) of a local unit vector (sphere::hemi_oct::encode).
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

@compute @workgroup_size(64)
fn shade(@builtin(global_invocation_id) gid: vec3<u32>) {
    let v = gid.x;
    if v >= u.counts.x {
        return;
    }
    let vertex = vertices[v];
    let n_len = length(vertex.normal.xyz);
    if !(n_len > 0.0) {
        radiance[v] = vec4<f32>(0.0, 0.0, 0.0, 1.0);
        return;
    }
    let n = vertex.normal.xyz / n_len;
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
    let leaf_count = u.counts.y;
    let partition_count = u.counts.z;
    let leaf_light = 3u * u.counts.w;

    var e = vec3<f32>(0.0);
    var spec = vec3<f32>(0.0);
    var pos = 0u;
    var si = 0u;
    var idx = cut_offsets[v];
    let idx_end = cut_offsets[v + 1u];
    loop {
        if pos >= leaf_count {
            break;
        }
        while si < partition_count && render_partition[si].range.y <= pos {
            si++;
        }
        if si >= partition_count {
            break;
        }
        let part = render_partition[si];
        var next = part.range.y;
        var vis = 0.0;
        var node = part.range.z;
        while idx < idx_end && cut_entries[idx].y <= pos {
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
        // A partition node wholly below the horizon contributes nothing.
        let axis = part.cone.xyz;
        let ccos = part.cone.w;
        let csin = sqrt(max(1.0 - ccos * ccos, 0.0));
        let cb = dot(axis, n);
        let sb = sqrt(max(1.0 - cb * cb, 0.0));
        if cb < 0.0 && cb * ccos + sb * csin <= 0.0 {
            continue;
        }
        let mr = light[3u * node];
        let mg = light[3u * node + 1u];
        let mb = light[3u * node + 2u];
        var above = cb * ccos - sb * csin > 0.0 && sb * ccos + cb * csin > 0.0;
        if !above {
            above = true;
            for (var i = a; i < z; i++) {
                if !leaf_wholly_above(leaves[i], n) {
                    above = false;
                    break;
                }
            }
        }
        var cos_power = vec3<f32>(0.0);
        if above {
            cos_power = max(vec3<f32>(dot(mr.xyz, n), dot(mg.xyz, n), dot(mb.xyz, n)), vec3<f32>(0.0));
        } else {
            for (var i = a; i < z; i++) {
                let ci = leaf_cosine_integral(i, n);
                if ci > 0.0 {
                    cos_power += light[leaf_light + i].xyz * ci;
                }
            }
        }
        if all(cos_power <= vec3<f32>(0.0)) {
            continue;
        }
        e += vis * cos_power;
        if !specular_on {
            continue;
        }
        let lum_moment = mr.xyz * LUMINANCE.x + mg.xyz * LUMINANCE.y + mb.xyz * LUMINANCE.z;
        let lum_len = length(lum_moment);
        if !(lum_len > 0.0) {
            continue;
        }
        let wi = to_local(frame, lum_moment / lum_len);
        if wi.z <= 0.0 {
            continue;
        }
        let hs = wi + wo;
        let hl = length(hs);
        if !(hl > 0.0) {
            continue;
        }
        let h = hs / hl;
        let s = static_term(wi, wo, h, f0);
        if s <= 0.0 {
            continue;
        }
        var spread = 0.0;
        if prefilter {
            let lum_power = dot(vec3<f32>(mr.w, mg.w, mb.w), LUMINANCE);
            if lum_power > 0.0 {
                spread = max(1.0 - lum_len / lum_power, 0.0) / (4.0 * max(dot(wo, h), 1e-3));
            }
        }
        spec += vis * cos_power * s * table_lookup(h, spread);
    }
    radiance[v] = vec4<f32>(u.rho_d_f0.xyz * INV_PI * e + spec, 1.0);
}
