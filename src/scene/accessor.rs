//! Checked reading of glTF accessors (this module replaces the gltf crate's `Reader`).
//!
//! Inputs: the validated JSON root, the loaded [`Buffers`], an accessor index and the role the
//! accessor plays. Outputs: decoded elements (`f32` vectors or `u32` indices).
//!
//! Invariants, all checked before a byte is read (failures are [`ImportError::Accessor`]):
//! * the accessor's type and component type suit its role: POSITION and NORMAL `VEC3` float,
//!   TANGENT `VEC4` float, TEXCOORD_0 `VEC2` float or normalized unsigned byte/short, indices
//!   `SCALAR` unsigned byte/short/int;
//! * `1 <= count <= MAX_ELEMENTS`;
//! * with a buffer view: `byteStride` (or the element size when absent) is at least the element
//!   size, `byteOffset + stride·(count−1) + elementSize` lies inside the view, and the view lies
//!   inside its buffer's declared length (computed in checked `u64` arithmetic);
//! * sparse parts: `1 <= sparse.count <= count`, the index and value ranges lie inside their views,
//!   the index component type is unsigned, and every sparse index is below `count`;
//! * POSITION values are finite.
//!
//! Decoding uses only bounds-checked slice access, so even an inconsistency that slipped past the
//! checks yields an error, never a panic.

use std::path::Path;

use gltf::json;
use gltf::json::accessor::{ComponentType, Type};
use gltf::json::validation::Checked;

use super::buffers::Buffers;
use super::error::ImportError;

/// Largest element count glint accepts for one accessor (64 Mi elements).
pub const MAX_ELEMENTS: u64 = 64 * 1024 * 1024;

/// What an accessor is used for; decides the accepted types.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Role {
    Position,
    Normal,
    Tangent,
    TexCoord,
    Indices,
}

impl Role {
    fn name(self) -> &'static str {
        match self {
            Role::Position => "POSITION",
            Role::Normal => "NORMAL",
            Role::Tangent => "TANGENT",
            Role::TexCoord => "TEXCOORD_0",
            Role::Indices => "indices",
        }
    }

    fn ty(self) -> Type {
        match self {
            Role::Position | Role::Normal => Type::Vec3,
            Role::Tangent => Type::Vec4,
            Role::TexCoord => Type::Vec2,
            Role::Indices => Type::Scalar,
        }
    }

    fn accepts(self, comp: ComponentType, normalized: bool) -> bool {
        match self {
            Role::Position | Role::Normal | Role::Tangent => comp == ComponentType::F32,
            Role::TexCoord => {
                comp == ComponentType::F32
                    || (normalized && matches!(comp, ComponentType::U8 | ComponentType::U16))
            }
            Role::Indices => {
                !normalized
                    && matches!(
                        comp,
                        ComponentType::U8 | ComponentType::U16 | ComponentType::U32
                    )
            }
        }
    }

    fn expected(self) -> &'static str {
        match self {
            Role::Position | Role::Normal => "VEC3 of FLOAT",
            Role::Tangent => "VEC4 of FLOAT",
            Role::TexCoord => {
                "VEC2 of FLOAT, normalized UNSIGNED_BYTE or normalized UNSIGNED_SHORT"
            }
            Role::Indices => "SCALAR of UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT",
        }
    }
}

/// Elements laid out with a stride in a byte slice that starts at element 0.
struct Strided<'a> {
    bytes: &'a [u8],
    stride: usize,
}

struct SparseLayout<'a> {
    count: usize,
    index_comp: ComponentType,
    indices: &'a [u8],
    values: &'a [u8],
}

/// A fully checked accessor.
struct Layout<'a> {
    count: usize,
    comp: ComponentType,
    dims: usize,
    normalized: bool,
    base: Option<Strided<'a>>,
    sparse: Option<SparseLayout<'a>>,
}

/// Reads accessors of one document.
pub(crate) struct AccessorReader<'a> {
    pub path: &'a Path,
    pub root: &'a json::Root,
    pub buffers: &'a Buffers,
}

fn comp_name(c: ComponentType) -> &'static str {
    match c {
        ComponentType::I8 => "BYTE",
        ComponentType::U8 => "UNSIGNED_BYTE",
        ComponentType::I16 => "SHORT",
        ComponentType::U16 => "UNSIGNED_SHORT",
        ComponentType::U32 => "UNSIGNED_INT",
        ComponentType::F32 => "FLOAT",
    }
}

fn type_name(t: Type) -> &'static str {
    match t {
        Type::Scalar => "SCALAR",
        Type::Vec2 => "VEC2",
        Type::Vec3 => "VEC3",
        Type::Vec4 => "VEC4",
        Type::Mat2 => "MAT2",
        Type::Mat3 => "MAT3",
        Type::Mat4 => "MAT4",
    }
}

/// One component as `f32`, normalized integers mapped to [0, 1] or [−1, 1] as glTF specifies.
fn component_f32(bytes: &[u8], at: usize, comp: ComponentType, normalized: bool) -> Option<f32> {
    let b = bytes.get(at..at.checked_add(comp.size())?)?;
    Some(match comp {
        ComponentType::F32 => f32::from_le_bytes(b.try_into().ok()?),
        ComponentType::U8 => {
            let v = f32::from(*b.first()?);
            if normalized { v / 255.0 } else { v }
        }
        ComponentType::I8 => {
            let v = f32::from(i8::from_le_bytes(b.try_into().ok()?));
            if normalized { (v / 127.0).max(-1.0) } else { v }
        }
        ComponentType::U16 => {
            let v = f32::from(u16::from_le_bytes(b.try_into().ok()?));
            if normalized { v / 65535.0 } else { v }
        }
        ComponentType::I16 => {
            let v = f32::from(i16::from_le_bytes(b.try_into().ok()?));
            if normalized {
                (v / 32767.0).max(-1.0)
            } else {
                v
            }
        }
        ComponentType::U32 => u32::from_le_bytes(b.try_into().ok()?) as f32,
    })
}

/// One unsigned integer component.
fn component_u32(bytes: &[u8], at: usize, comp: ComponentType) -> Option<u32> {
    let b = bytes.get(at..at.checked_add(comp.size())?)?;
    match comp {
        ComponentType::U8 => Some(u32::from(*b.first()?)),
        ComponentType::U16 => Some(u32::from(u16::from_le_bytes(b.try_into().ok()?))),
        ComponentType::U32 => Some(u32::from_le_bytes(b.try_into().ok()?)),
        _ => None,
    }
}

impl<'a> AccessorReader<'a> {
    fn err(&self, accessor: usize, message: impl Into<String>) -> ImportError {
        ImportError::Accessor {
            path: self.path.to_path_buf(),
            accessor,
            message: message.into(),
        }
    }

    /// The bytes of buffer view `view`, checked to lie inside its buffer.
    fn view_bytes(
        &self,
        accessor: usize,
        view: usize,
        what: &str,
    ) -> Result<(&'a [u8], Option<usize>), ImportError> {
        let Some(v) = self.root.buffer_views.get(view) else {
            return Err(self.err(
                accessor,
                format!("{what} buffer view {view} does not exist"),
            ));
        };
        let buffer = v.buffer.value();
        let Some(data) = self.buffers.get(buffer) else {
            return Err(self.err(
                accessor,
                format!("buffer view {view} refers to buffer {buffer}, which does not exist"),
            ));
        };
        let offset = v.byte_offset.map_or(0, |o| o.0);
        let length = v.byte_length.0;
        let end = offset.checked_add(length);
        match end {
            Some(end) if end <= data.len() as u64 => {
                // offset <= end <= data.len(), so both fit in usize.
                let range = offset as usize..end as usize;
                let bytes = data.get(range).unwrap_or(&[]);
                let stride = v.byte_stride.map(|s| s.0).filter(|&s| s > 0);
                Ok((bytes, stride))
            }
            _ => Err(self.err(
                accessor,
                format!(
                    "buffer view {view} (bytes {offset}..{}) exceeds buffer {buffer} of {} bytes",
                    offset.saturating_add(length),
                    data.len()
                ),
            )),
        }
    }

    /// Validates accessor `index` for `role`.
    fn layout(&self, index: usize, role: Role) -> Result<Layout<'a>, ImportError> {
        let Some(acc) = self.root.accessors.get(index) else {
            return Err(self.err(index, "does not exist"));
        };
        let (Checked::Valid(comp), Checked::Valid(ty)) = (acc.component_type, acc.type_) else {
            return Err(self.err(index, "invalid componentType or type"));
        };
        let comp = comp.0;
        if ty != role.ty() || !role.accepts(comp, acc.normalized) {
            return Err(self.err(
                index,
                format!(
                    "{} must be {}, found {} of {}{}",
                    role.name(),
                    role.expected(),
                    type_name(ty),
                    if acc.normalized { "normalized " } else { "" },
                    comp_name(comp)
                ),
            ));
        }
        let count64 = acc.count.0;
        if count64 == 0 {
            return Err(self.err(index, format!("{} accessor has count 0", role.name())));
        }
        if count64 > MAX_ELEMENTS {
            return Err(self.err(
                index,
                format!("count {count64} exceeds glint's limit of {MAX_ELEMENTS} elements"),
            ));
        }
        let count = count64 as usize; // <= MAX_ELEMENTS
        let dims = ty.multiplicity();
        let elem = comp.size() * dims; // at most 4 * 16
        let elem64 = elem as u64;

        let base = match acc.buffer_view {
            Some(view) => {
                let (bytes, stride) = self.view_bytes(index, view.value(), "its")?;
                let stride = stride.unwrap_or(elem);
                if stride < elem {
                    return Err(self.err(
                        index,
                        format!("byteStride {stride} is smaller than the element size {elem}"),
                    ));
                }
                let offset = acc.byte_offset.map_or(0, |o| o.0);
                let needed = (stride as u64)
                    .checked_mul(count64 - 1) // count64 >= 1
                    .and_then(|x| x.checked_add(offset))
                    .and_then(|x| x.checked_add(elem64));
                match needed {
                    Some(n) if n <= bytes.len() as u64 => {}
                    _ => {
                        return Err(self.err(
                            index,
                            format!(
                                "{count64} elements of {elem} bytes at offset {offset} with stride {stride} do not fit in buffer view {} of {} bytes",
                                view.value(),
                                bytes.len()
                            ),
                        ));
                    }
                }
                // offset < needed <= bytes.len(), so it fits in usize.
                let bytes = bytes.get(offset as usize..).unwrap_or(&[]);
                Some(Strided { bytes, stride })
            }
            None => None,
        };

        let sparse = match &acc.sparse {
            None => None,
            Some(sp) => {
                let scount = sp.count.0;
                if scount == 0 || scount > count64 {
                    return Err(self.err(
                        index,
                        format!("sparse count {scount} is not in 1..={count64}"),
                    ));
                }
                let scount_usize = scount as usize; // <= count
                let Checked::Valid(icomp) = sp.indices.component_type else {
                    return Err(self.err(index, "sparse indices have an invalid componentType"));
                };
                let icomp = icomp.0;
                if !matches!(
                    icomp,
                    ComponentType::U8 | ComponentType::U16 | ComponentType::U32
                ) {
                    return Err(self.err(index, "sparse indices must be unsigned integers"));
                }
                let (ibytes, _) =
                    self.view_bytes(index, sp.indices.buffer_view.value(), "sparse indices")?;
                let (vbytes, _) =
                    self.view_bytes(index, sp.values.buffer_view.value(), "sparse values")?;
                let slice = |bytes: &'a [u8], offset: u64, size: u64, what: &str| {
                    let end = scount.checked_mul(size).and_then(|x| x.checked_add(offset));
                    match end {
                        // offset <= end <= bytes.len()
                        Some(end) if end <= bytes.len() as u64 => {
                            Ok(bytes.get(offset as usize..end as usize).unwrap_or(&[]))
                        }
                        _ => Err(self.err(
                            index,
                            format!(
                                "sparse {what}: {scount} entries of {size} bytes at offset {offset} do not fit in their buffer view of {} bytes",
                                bytes.len()
                            ),
                        )),
                    }
                };
                let indices = slice(
                    ibytes,
                    sp.indices.byte_offset.0,
                    icomp.size() as u64,
                    "indices",
                )?;
                let values = slice(vbytes, sp.values.byte_offset.0, elem64, "values")?;
                Some(SparseLayout {
                    count: scount_usize,
                    index_comp: icomp,
                    indices,
                    values,
                })
            }
        };
        if base.is_none() && sparse.is_none() {
            return Err(self.err(index, "has neither a bufferView nor sparse data"));
        }
        Ok(Layout {
            count,
            comp,
            dims,
            normalized: acc.normalized,
            base,
            sparse,
        })
    }

    /// Decodes a float accessor into `count · dims` values.
    fn read_f32(&self, index: usize, role: Role) -> Result<(Vec<f32>, usize), ImportError> {
        let l = self.layout(index, role)?;
        let size = l.comp.size();
        let short = || self.err(index, "data ends early (internal check failed)");
        let mut out = vec![0.0f32; l.count * l.dims]; // count <= MAX_ELEMENTS, dims <= 16
        if let Some(base) = &l.base {
            for (i, element) in out.chunks_exact_mut(l.dims).enumerate() {
                let start = i * base.stride; // < bytes.len() by the range check
                for (c, v) in element.iter_mut().enumerate() {
                    *v = component_f32(base.bytes, start + c * size, l.comp, l.normalized)
                        .ok_or_else(short)?;
                }
            }
        }
        if let Some(sp) = &l.sparse {
            let isize_ = sp.index_comp.size();
            let elem = size * l.dims;
            for k in 0..sp.count {
                let target =
                    component_u32(sp.indices, k * isize_, sp.index_comp).ok_or_else(short)?;
                let t = target as usize;
                // t < count <= MAX_ELEMENTS is checked first, so the products cannot overflow.
                let slot = (t < l.count).then(|| t * l.dims..(t + 1) * l.dims);
                let Some(element) = slot.and_then(|r| out.get_mut(r)) else {
                    return Err(self.err(
                        index,
                        format!("sparse index {target} is not below count {}", l.count),
                    ));
                };
                for (c, v) in element.iter_mut().enumerate() {
                    *v = component_f32(sp.values, k * elem + c * size, l.comp, l.normalized)
                        .ok_or_else(short)?;
                }
            }
        }
        Ok((out, l.dims))
    }

    /// Reads a POSITION or NORMAL accessor.
    pub fn vec3(&self, index: usize, role: Role) -> Result<Vec<glam::Vec3>, ImportError> {
        let (flat, _) = self.read_f32(index, role)?;
        let out: Vec<glam::Vec3> = flat
            .chunks_exact(3)
            .map(|c| glam::Vec3::new(c[0], c[1], c[2])) // chunks of exactly 3
            .collect();
        if role == Role::Position && out.iter().any(|p| !p.is_finite()) {
            return Err(self.err(index, "POSITION holds NaN or infinite values"));
        }
        Ok(out)
    }

    /// Reads a TANGENT accessor.
    pub fn vec4(&self, index: usize, role: Role) -> Result<Vec<glam::Vec4>, ImportError> {
        let (flat, _) = self.read_f32(index, role)?;
        Ok(flat
            .chunks_exact(4)
            .map(|c| glam::Vec4::new(c[0], c[1], c[2], c[3])) // chunks of exactly 4
            .collect())
    }

    /// Reads a TEXCOORD accessor.
    pub fn vec2(&self, index: usize, role: Role) -> Result<Vec<glam::Vec2>, ImportError> {
        let (flat, _) = self.read_f32(index, role)?;
        Ok(flat
            .chunks_exact(2)
            .map(|c| glam::Vec2::new(c[0], c[1])) // chunks of exactly 2
            .collect())
    }

    /// Reads an index accessor.
    pub fn indices(&self, index: usize) -> Result<Vec<u32>, ImportError> {
        let l = self.layout(index, Role::Indices)?;
        let short = || self.err(index, "data ends early (internal check failed)");
        let mut out = vec![0u32; l.count];
        if let Some(base) = &l.base {
            for (i, v) in out.iter_mut().enumerate() {
                *v = component_u32(base.bytes, i * base.stride, l.comp).ok_or_else(short)?;
            }
        }
        if let Some(sp) = &l.sparse {
            let isize_ = sp.index_comp.size();
            let size = l.comp.size();
            for k in 0..sp.count {
                let target =
                    component_u32(sp.indices, k * isize_, sp.index_comp).ok_or_else(short)?;
                let Some(slot) = out.get_mut(target as usize) else {
                    return Err(self.err(
                        index,
                        format!("sparse index {target} is not below count {}", l.count),
                    ));
                };
                *slot = component_u32(sp.values, k * size, l.comp).ok_or_else(short)?;
            }
        }
        Ok(out)
    }
}
