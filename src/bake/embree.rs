//! Occlusion rays through Intel Embree 3 (Debian's `libembree-dev`), where `build.rs` finds it
//! (`cfg(embree)`).
//!
//! Inputs: the mesh's vertices and its non-degenerate triangles. Outputs: [`EmbreeTracer::occluded`],
//! the same any-hit answer as [`super::tracer::Tracer::occluded`] for a ray from `origin` along
//! `dir`, t in [0, ∞), from Embree's own BVH and `rtcOccluded1` (robust triangle test, so a ray
//! through a shared edge is never let through); [`EmbreeTracer::occluded_from`], many rays from
//! one origin: in a large scene ([`STREAM_TRIANGLES`]) from [`STREAM_MIN`] rays on as one stream
//! (`rtcOccluded1M`, incoherent: Embree sorts the stream's rays by octant and traverses them
//! together), else in packets of 16 (`rtcOccluded16`; a last one of at most 8 rays as
//! `rtcOccluded8`); [`EmbreeTracer::occluded_each`], rays from many origins as one stream.
//!
//! The binding is the few C entry points it needs, declared here against Embree 3.13's headers
//! (`/usr/include/embree3`; `build.rs` checks their configuration); nothing else of Embree is
//! used.
//!
//! Invariants: the scene is committed before any query and never changed after, so queries from any
//! number of threads are safe (Embree's documented contract for committed scenes); no IO.

use glam::{Vec3, Vec3A};
use std::ffi::{c_char, c_int, c_uint, c_void};

#[repr(C)]
struct RtcIntersectContext {
    flags: c_uint,
    filter: *const c_void,
    inst_id: [c_uint; 1],
}

#[repr(C, align(16))]
struct RtcRay {
    org: [f32; 3],
    tnear: f32,
    dir: [f32; 3],
    time: f32,
    tfar: f32,
    mask: c_uint,
    id: c_uint,
    flags: c_uint,
}

type RtcDevice = *mut c_void;
type RtcScene = *mut c_void;
type RtcGeometry = *mut c_void;

const GEOMETRY_TYPE_TRIANGLE: c_uint = 0;
const BUFFER_TYPE_INDEX: c_uint = 0;
const BUFFER_TYPE_VERTEX: c_uint = 1;
const FORMAT_UINT3: c_uint = 0x5003;
const FORMAT_FLOAT3: c_uint = 0x9003;
const BUILD_QUALITY_HIGH: c_uint = 2;
const SCENE_FLAG_ROBUST: c_uint = 1 << 2;
const INVALID_GEOMETRY_ID: c_uint = u32::MAX;
const CONTEXT_INCOHERENT: c_uint = 0;
/// A vertex's rays in leaf order point alike: with this hint Embree's packets traced 1.1–1.3× the
/// rays per second of the incoherent hint (`cargo bench --bench bake -- rays`, all three meshes).
const CONTEXT_COHERENT: c_uint = 1;

#[link(name = "embree3")]
unsafe extern "C" {
    fn rtcNewDevice(config: *const c_char) -> RtcDevice;
    fn rtcReleaseDevice(device: RtcDevice);
    fn rtcGetDeviceError(device: RtcDevice) -> c_int;
    fn rtcNewScene(device: RtcDevice) -> RtcScene;
    fn rtcReleaseScene(scene: RtcScene);
    fn rtcSetSceneBuildQuality(scene: RtcScene, quality: c_uint);
    fn rtcSetSceneFlags(scene: RtcScene, flags: c_uint);
    fn rtcCommitScene(scene: RtcScene);
    fn rtcNewGeometry(device: RtcDevice, kind: c_uint) -> RtcGeometry;
    fn rtcReleaseGeometry(geometry: RtcGeometry);
    fn rtcSetNewGeometryBuffer(
        geometry: RtcGeometry,
        kind: c_uint,
        slot: c_uint,
        format: c_uint,
        byte_stride: usize,
        count: usize,
    ) -> *mut c_void;
    fn rtcCommitGeometry(geometry: RtcGeometry);
    fn rtcSetGeometryBuildQuality(geometry: RtcGeometry, quality: c_uint);
    fn rtcAttachGeometry(scene: RtcScene, geometry: RtcGeometry) -> c_uint;
    fn rtcOccluded1(scene: RtcScene, context: *mut RtcIntersectContext, ray: *mut RtcRay);
    fn rtcOccluded1M(
        scene: RtcScene,
        context: *mut RtcIntersectContext,
        ray: *mut RtcRay,
        m: c_uint,
        byte_stride: usize,
    );
    fn rtcOccluded8(
        valid: *const c_int,
        scene: RtcScene,
        context: *mut RtcIntersectContext,
        ray: *mut RtcRayN<8>,
    );
    fn rtcOccluded16(
        valid: *const c_int,
        scene: RtcScene,
        context: *mut RtcIntersectContext,
        ray: *mut RtcRayN<16>,
    );
}

/// `RTCRay8` / `RTCRay16` (must match Embree 3.13's `rtcore_ray.h`: each field an array by lane,
/// 32- and 64-byte aligned respectively, so 64 serves both).
#[repr(C, align(64))]
struct RtcRayN<const N: usize> {
    org: [[f32; N]; 3],
    tnear: [f32; N],
    dir: [[f32; N]; 3],
    time: [f32; N],
    tfar: [f32; N],
    mask: [c_uint; N],
    id: [c_uint; N],
    flags: [c_uint; N],
}

#[repr(C, align(64))]
struct ValidN<const N: usize>([c_int; N]);

type OccludedN<const N: usize> =
    unsafe extern "C" fn(*const c_int, RtcScene, *mut RtcIntersectContext, *mut RtcRayN<N>);

/// Calls of [`EmbreeTracer::occluded_from`] with at least this many rays go to Embree as one
/// stream, in a scene of at least [`STREAM_TRIANGLES`] triangles; the rest, in packets. From
/// `cargo bench --bench bake -- rays` (a vertex's rays traced in calls of 8 to 128 consecutive
/// directions, the sizes of the bake's calls; docs/benchmarks.md): on dragon_100k the stream
/// traced 1.1–1.2× the rays per second of packets of 16 in calls of 32 rays and more, and about
/// the same in calls of 8 and 16.
pub const STREAM_MIN: usize = 32;

/// Scenes of at least this many triangles use Embree's streams ([`STREAM_MIN`]). Its stream
/// traversal shares each BVH node it fetches among up to 64 rays, which pays once the BVH outgrows
/// a core's cache. In whole bakes (two binaries alternating, with and without streams, the same
/// cuts; docs/benchmarks.md, "Streams"): dragon.glb (30 K triangles) baked 2–11 % faster under
/// studio_1k and interior_1k, suzanne (15 K) about 5 % faster under both, while the bunny (3.7 K)
/// and the teapot (1 K) came out even within the noise; in the rays bench's isolated calls the
/// bunny's stream traced 0.6× as fast as packets (`cargo bench --bench bake -- rays`).
pub const STREAM_TRIANGLES: usize = 8_192;

thread_local! {
    /// [`EmbreeTracer::occluded_stream`]'s rays, kept per thread between calls.
    static STREAM: std::cell::RefCell<Vec<RtcRay>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// A committed Embree scene of the mesh's triangles.
pub struct EmbreeTracer {
    device: RtcDevice,
    scene: RtcScene,
    /// Whether [`EmbreeTracer::occluded_from`] may use streams: a scene of at least
    /// [`STREAM_TRIANGLES`] triangles.
    stream: bool,
}

// SAFETY: the scene is committed in `new` and never modified; Embree allows concurrent queries on
// a committed scene, and the device and scene are released once, in `drop`.
unsafe impl Send for EmbreeTracer {}
unsafe impl Sync for EmbreeTracer {}

/// Embree could not build the scene (out of memory, or an unsupported CPU).
#[derive(Debug, thiserror::Error)]
#[error("Embree failed to build the scene (error code {0})")]
pub struct EmbreeError(i32);

impl EmbreeTracer {
    /// Builds Embree's BVH over the triangles `indices` (into `positions`) (robust traversal). The
    /// caller leaves out degenerate triangles and checks the indices ([`super::tracer::Tracer`]
    /// does).
    pub fn new(positions: &[Vec3], indices: &[[u32; 3]]) -> Result<Self, EmbreeError> {
        // SAFETY: every pointer passed below comes from Embree itself, checked non-null, and the
        // buffers are written within the sizes asked for.
        unsafe {
            // Embree builds its BVH on as many threads as the bake's other stages run (rayon's
            // pool: `RAYON_NUM_THREADS` where a scheduler grants a share of a node's cores).
            // (A formatted number holds no NUL; were it to, Embree's defaults would do.)
            let config =
                std::ffi::CString::new(format!("threads={}", rayon::current_num_threads()))
                    .unwrap_or_default();
            let device = rtcNewDevice(config.as_ptr());
            if device.is_null() {
                return Err(EmbreeError(-1));
            }
            let scene = rtcNewScene(device);
            let this = Self {
                device,
                scene,
                stream: indices.len() >= STREAM_TRIANGLES,
            };
            // High quality (spatial splits) traced dragon_100k's bake rays 1.2–1.8× faster than
            // low or medium, and the compact layout, which saves ~40 MiB at 1.6 M triangles,
            // 1.2× slower (`cargo bench --bench bake -- rays million`).
            rtcSetSceneBuildQuality(scene, BUILD_QUALITY_HIGH);
            rtcSetSceneFlags(scene, SCENE_FLAG_ROBUST);
            if !indices.is_empty() {
                let geometry = rtcNewGeometry(device, GEOMETRY_TYPE_TRIANGLE);
                rtcSetGeometryBuildQuality(geometry, BUILD_QUALITY_HIGH);
                let vertices = rtcSetNewGeometryBuffer(
                    geometry,
                    BUFFER_TYPE_VERTEX,
                    0,
                    FORMAT_FLOAT3,
                    12,
                    positions.len(),
                ) as *mut [f32; 3];
                let index = rtcSetNewGeometryBuffer(
                    geometry,
                    BUFFER_TYPE_INDEX,
                    0,
                    FORMAT_UINT3,
                    12,
                    indices.len(),
                ) as *mut [u32; 3];
                if vertices.is_null() || index.is_null() {
                    rtcReleaseGeometry(geometry);
                    return Err(EmbreeError(rtcGetDeviceError(device)));
                }
                let vertices = std::slice::from_raw_parts_mut(vertices, positions.len());
                for (v, p) in vertices.iter_mut().zip(positions) {
                    *v = p.to_array();
                }
                std::slice::from_raw_parts_mut(index, indices.len()).copy_from_slice(indices);
                rtcCommitGeometry(geometry);
                rtcAttachGeometry(scene, geometry);
                rtcReleaseGeometry(geometry);
            }
            rtcCommitScene(scene);
            match rtcGetDeviceError(device) {
                0 => Ok(this),
                e => Err(EmbreeError(e)),
            }
        }
    }

    /// Any hit along the ray (origin, dir) for t in [0, ∞).
    #[inline]
    pub fn occluded(&self, origin: Vec3A, dir: Vec3A) -> bool {
        let mut context = RtcIntersectContext {
            flags: CONTEXT_INCOHERENT,
            filter: std::ptr::null(),
            inst_id: [INVALID_GEOMETRY_ID],
        };
        let mut ray = RtcRay {
            org: origin.to_array(),
            tnear: 0.0,
            dir: dir.to_array(),
            time: 0.0,
            tfar: f32::INFINITY,
            mask: u32::MAX,
            id: 0,
            flags: 0,
        };
        // SAFETY: the scene is committed; context and ray are valid for the call.
        unsafe { rtcOccluded1(self.scene, &mut context, &mut ray) };
        ray.tfar == f32::NEG_INFINITY
    }

    /// `out[i]` = [`EmbreeTracer::occluded`] of the ray from `origin` along `dirs[i]`: in a
    /// scene of at least [`STREAM_TRIANGLES`] triangles as one stream from [`STREAM_MIN`] rays on
    /// ([`EmbreeTracer::occluded_stream`]), else in packets
    /// ([`EmbreeTracer::occluded_from_packets`]).
    pub fn occluded_from(&self, origin: Vec3A, dirs: &[Vec3A], out: &mut [bool]) {
        if self.stream && dirs.len() >= STREAM_MIN {
            self.occluded_stream(origin, dirs, out);
        } else {
            self.occluded_from_packets(origin, dirs, out);
        }
    }

    /// [`EmbreeTracer::occluded_from`] as one stream of single rays (`rtcOccluded1M`) with the
    /// incoherent hint, under which Embree 3 sorts the stream by octant and traverses up to 64
    /// rays at once (its stream traversal); with the coherent hint it would cut the stream into
    /// packets in order, as [`EmbreeTracer::occluded_from_packets`] does.
    pub fn occluded_stream(&self, origin: Vec3A, dirs: &[Vec3A], out: &mut [bool]) {
        self.stream_of(dirs.iter().map(|d| (origin, *d)), out);
    }

    /// `out[i]` = [`EmbreeTracer::occluded`] of the ray from `origins[i]` along `dirs[i]`, as
    /// one stream ([`EmbreeTracer::occluded_stream`]): for the rays of many neighbouring points,
    /// which Embree sorts by octant and traverses together.
    pub fn occluded_each(&self, origins: &[Vec3A], dirs: &[Vec3A], out: &mut [bool]) {
        self.stream_of(origins.iter().copied().zip(dirs.iter().copied()), out);
    }

    /// The rays (origin, direction) as one stream of single rays (`rtcOccluded1M`, incoherent).
    fn stream_of(&self, rays_in: impl Iterator<Item = (Vec3A, Vec3A)>, out: &mut [bool]) {
        let mut context = RtcIntersectContext {
            flags: CONTEXT_INCOHERENT,
            filter: std::ptr::null(),
            inst_id: [INVALID_GEOMETRY_ID],
        };
        STREAM.with_borrow_mut(|rays| {
            rays.clear();
            rays.extend(rays_in.map(|(origin, d)| RtcRay {
                org: origin.to_array(),
                tnear: 0.0,
                dir: d.to_array(),
                time: 0.0,
                tfar: f32::INFINITY,
                mask: u32::MAX,
                id: 0,
                flags: 0,
            }));
            for (chunk, o) in rays
                .chunks_mut(c_uint::MAX as usize)
                .zip(out.chunks_mut(c_uint::MAX as usize))
            {
                // SAFETY: the scene is committed; `chunk` holds `chunk.len()` valid rays laid out
                // as Embree's `RTCRay` (48 bytes, 16-byte aligned), `size_of::<RtcRay>()` apart.
                unsafe {
                    rtcOccluded1M(
                        self.scene,
                        &mut context,
                        chunk.as_mut_ptr(),
                        chunk.len() as c_uint,
                        std::mem::size_of::<RtcRay>(),
                    )
                };
                for (o, r) in o.iter_mut().zip(chunk.iter()) {
                    *o = r.tfar == f32::NEG_INFINITY;
                }
            }
        });
    }

    /// [`EmbreeTracer::occluded_from`] in packets of 16 (`rtcOccluded16`, coherent), the last as
    /// a packet of 8 where at most 8 rays are left: 16 traced 1.1–1.4× the rays per second of 8
    /// (`cargo bench --bench bake -- rays`), but a half-empty 16 cost the bunny's bake under
    /// interior_1k, whose boundary levels trace a few quarters at a time, ~10 % (4 alternating
    /// pairs). What every call used before the stream; kept for calls of fewer than
    /// [`STREAM_MIN`] rays and for the benches' side by side.
    pub fn occluded_from_packets(&self, origin: Vec3A, dirs: &[Vec3A], out: &mut [bool]) {
        let n = dirs.len();
        let sixteens = if n % 16 > 8 { n } else { n / 16 * 16 };
        let (dirs, tail) = dirs.split_at(sixteens);
        let (out, out_tail) = out.split_at_mut(sixteens);
        self.occluded_packets::<16>(rtcOccluded16, origin, dirs, out);
        self.occluded_packets::<8>(rtcOccluded8, origin, tail, out_tail);
    }

    /// [`EmbreeTracer::occluded_from`] in packets of 8 (`rtcOccluded8`), for the benches' side by
    /// side.
    pub fn occluded_from_8(&self, origin: Vec3A, dirs: &[Vec3A], out: &mut [bool]) {
        self.occluded_packets::<8>(rtcOccluded8, origin, dirs, out);
    }

    /// `out[i]` = [`EmbreeTracer::occluded`] of the ray from `origins[i]` along `dirs[i]`, in
    /// packets of 16 as [`EmbreeTracer::occluded_from`] traces them, each ray from its own origin:
    /// for rays of one direction from neighbouring points (the rays bench's grouping across
    /// vertices).
    pub fn occluded_rays(&self, origins: &[Vec3A], dirs: &[Vec3A], out: &mut [bool]) {
        let mut context = RtcIntersectContext {
            flags: CONTEXT_COHERENT,
            filter: std::ptr::null(),
            inst_id: [INVALID_GEOMETRY_ID],
        };
        for ((p, d), o) in origins
            .chunks(16)
            .zip(dirs.chunks(16))
            .zip(out.chunks_mut(16))
        {
            let mut valid = ValidN([0; 16]);
            let mut ray = RtcRayN::<16> {
                org: [[0.0; 16]; 3],
                tnear: [0.0; 16],
                dir: [[0.0; 16]; 3],
                time: [0.0; 16],
                tfar: [f32::INFINITY; 16],
                mask: [u32::MAX; 16],
                id: [0; 16],
                flags: [0; 16],
            };
            for (lane, (origin, dir)) in p.iter().zip(d).enumerate() {
                valid.0[lane] = -1;
                for axis in 0..3 {
                    ray.org[axis][lane] = origin[axis];
                    ray.dir[axis][lane] = dir[axis];
                }
            }
            // SAFETY: the scene is committed; valid and ray are 64-byte aligned and valid for the
            // call.
            unsafe { rtcOccluded16(valid.0.as_ptr(), self.scene, &mut context, &mut ray) };
            for (lane, o) in o.iter_mut().enumerate() {
                *o = ray.tfar[lane] == f32::NEG_INFINITY;
            }
        }
    }

    fn occluded_packets<const N: usize>(
        &self,
        trace: OccludedN<N>,
        origin: Vec3A,
        dirs: &[Vec3A],
        out: &mut [bool],
    ) {
        let mut context = RtcIntersectContext {
            flags: CONTEXT_COHERENT,
            filter: std::ptr::null(),
            inst_id: [INVALID_GEOMETRY_ID],
        };
        for (d, o) in dirs.chunks(N).zip(out.chunks_mut(N)) {
            let mut valid = ValidN([0; N]);
            let mut ray = RtcRayN::<N> {
                org: [[origin.x; N], [origin.y; N], [origin.z; N]],
                tnear: [0.0; N],
                dir: [[0.0; N]; 3],
                time: [0.0; N],
                tfar: [f32::INFINITY; N],
                mask: [u32::MAX; N],
                id: [0; N],
                flags: [0; N],
            };
            for (lane, dir) in d.iter().enumerate() {
                valid.0[lane] = -1;
                ray.dir[0][lane] = dir.x;
                ray.dir[1][lane] = dir.y;
                ray.dir[2][lane] = dir.z;
            }
            // SAFETY: the scene is committed; valid and ray are 64-byte aligned and valid for the
            // call, and `trace` is Embree's entry point for packets of N.
            unsafe { trace(valid.0.as_ptr(), self.scene, &mut context, &mut ray) };
            for (lane, o) in o.iter_mut().enumerate() {
                *o = ray.tfar[lane] == f32::NEG_INFINITY;
            }
        }
    }
}

impl Drop for EmbreeTracer {
    fn drop(&mut self) {
        // SAFETY: released once; no query can be in flight while `self` is being dropped.
        unsafe {
            rtcReleaseScene(self.scene);
            rtcReleaseDevice(self.device);
        }
    }
}
