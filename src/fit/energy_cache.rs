//! Where a fit gets its energy rows: remembered in the process, then read from a disk cache under a
//! content hash, else integrated ([`EnergyTable::with_defaults`]) and written there.
//!
//! The table is a pure function of the lobe centres, λ, the outgoing directions and the quadrature
//! (F0 enters as g = F0·a + b), so a file named by the hash of exactly those, plus
//! [`CACHE_VERSION`], can be shared by every process and machine that fits with the same lobes.
//!
//! File `energy-<16 hex>.bin` (little-endian): `b"GLINTENG"` · u32 [`CACHE_VERSION`] · u64 the key
//! · u32 N_l · u32 J · N_l × 3 f64 outgoing directions · N_l·J f64 a · N_l·J f64 b · u64 FNV-1a of
//! every byte before it.
//!
//! Inputs: a [`LobeSet`]; the cache folder, set once per process by the caller ([`set_dir`]; the
//! CLI takes it from `GLINT_CACHE_DIR`, else `$XDG_CACHE_HOME/glint`, else `~/.cache/glint`).
//! Outputs: the table. Invariants: a cached table is bit for bit the table integration gives
//! (f64 stored as bits; the integration is deterministic); a file that is truncated, corrupt, of
//! another version or for other inputs is ignored and rewritten, never trusted; writes are atomic,
//! and a cache that cannot be written (read-only, full) costs the next process the integration,
//! nothing else.

use crate::brdf::EnergyTable;
use crate::brdf::energy::{EnergyQuadrature, default_outgoing};
use crate::math::fnv1a64;
use crate::sphere::LobeSet;
use glam::DVec3;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Bump when the integration changes what it computes for the same inputs (quadrature rules,
/// constraints, the static term), so that tables integrated the old way are not reused.
pub const CACHE_VERSION: u32 = 1;
const MAGIC: &[u8; 8] = b"GLINTENG";
/// Tables kept in memory per process.
const MEMORY_SLOTS: usize = 8;

static DIR: Mutex<Option<PathBuf>> = Mutex::new(None);
static MEMORY: Mutex<Vec<(u64, Arc<EnergyTable>)>> = Mutex::new(Vec::new());

/// Sets (or with `None` turns off) the disk cache's folder for this process.
pub fn set_dir(dir: Option<PathBuf>) {
    if let Ok(mut d) = DIR.lock() {
        *d = dir;
    }
}

/// The folder [`set_dir`] set.
pub fn dir() -> Option<PathBuf> {
    DIR.lock().ok().and_then(|d| d.clone())
}

/// Where a table came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    Memory,
    Disk,
    Integrated,
}

/// The default table for `lobes`: from memory, the disk cache ([`dir`]) or integration.
pub fn table(lobes: &LobeSet) -> Arc<EnergyTable> {
    table_in(lobes, dir().as_deref()).0
}

/// [`table`] with an explicit cache folder (`None`: memory only), and where it came from.
pub fn table_in(lobes: &LobeSet, dir: Option<&Path>) -> (Arc<EnergyTable>, Source) {
    let outgoing = default_outgoing(lobes);
    let quad = EnergyQuadrature::default();
    let key = key(lobes, &outgoing, &quad);
    let remembered = MEMORY
        .lock()
        .ok()
        .and_then(|m| m.iter().find(|(k, _)| *k == key).map(|(_, t)| t.clone()));
    if let Some(hit) = remembered {
        return (hit, Source::Memory);
    }
    let (table, source) =
        match dir.and_then(|d| read(&d.join(file_name(key)), key, &outgoing, lobes.len())) {
            Some(table) => (table, Source::Disk),
            None => {
                let table = EnergyTable::new(lobes, &outgoing, &quad);
                if let Some(d) = dir {
                    // Best effort: a cache that cannot be written only costs a later process the
                    // integration.
                    let _ = std::fs::create_dir_all(d).map(|()| {
                        glint_exporters::write_atomic(&d.join(file_name(key)), &encode(&table, key))
                    });
                }
                (table, Source::Integrated)
            }
        };
    let table = Arc::new(table);
    if let Ok(mut m) = MEMORY.lock() {
        if m.len() >= MEMORY_SLOTS {
            m.remove(0);
        }
        m.push((key, table.clone()));
    }
    (table, source)
}

/// The default table for `lobes` from the disk cache in `dir` only (`None`: not there, or not
/// intact).
pub fn load(lobes: &LobeSet, dir: &Path) -> Option<EnergyTable> {
    let outgoing = default_outgoing(lobes);
    let key = key(lobes, &outgoing, &EnergyQuadrature::default());
    read(&dir.join(file_name(key)), key, &outgoing, lobes.len())
}

fn file_name(key: u64) -> String {
    format!("energy-{key:016x}.bin")
}

/// The content hash: everything the table is a function of.
fn key(lobes: &LobeSet, outgoing: &[DVec3], quad: &EnergyQuadrature) -> u64 {
    let mut bytes = Vec::new();
    bytes.extend_from_slice(MAGIC);
    bytes.extend_from_slice(&CACHE_VERSION.to_le_bytes());
    bytes.extend_from_slice(&lobes.lambda().to_bits().to_le_bytes());
    let mut vectors = |vs: &[DVec3]| {
        bytes.extend_from_slice(&(vs.len() as u64).to_le_bytes());
        for v in vs {
            for x in v.to_array() {
                bytes.extend_from_slice(&x.to_bits().to_le_bytes());
            }
        }
    };
    vectors(lobes.centres());
    vectors(outgoing);
    bytes.push(lobes.layout().is_isotropic() as u8);
    for n in [
        quad.azimuth_points,
        quad.radial_points,
        quad.ring_points,
        quad.cut_refinement,
    ] {
        bytes.extend_from_slice(&(n as u64).to_le_bytes());
    }
    fnv1a64(&bytes)
}

fn encode(table: &EnergyTable, key: u64) -> Vec<u8> {
    let (a, b) = table.parts();
    let mut out = Vec::with_capacity(32 + 8 * (3 * table.rows() + a.len() + b.len()));
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&CACHE_VERSION.to_le_bytes());
    out.extend_from_slice(&key.to_le_bytes());
    out.extend_from_slice(&(table.rows() as u32).to_le_bytes());
    out.extend_from_slice(&(table.cols() as u32).to_le_bytes());
    let values = table.outgoing().iter().flat_map(|v| v.to_array());
    for x in values.chain(a.iter().copied()).chain(b.iter().copied()) {
        out.extend_from_slice(&x.to_bits().to_le_bytes());
    }
    let sum = fnv1a64(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    out
}

/// The cached table at `path`, if it is intact and for exactly these inputs.
fn read(path: &Path, key: u64, outgoing: &[DVec3], cols: usize) -> Option<EnergyTable> {
    let bytes = std::fs::read(path).ok()?;
    decode(&bytes, key, outgoing, cols)
}

fn decode(bytes: &[u8], key: u64, outgoing: &[DVec3], cols: usize) -> Option<EnergyTable> {
    let (body, sum) = bytes.split_at_checked(bytes.len().checked_sub(8)?)?;
    if fnv1a64(body) != u64::from_le_bytes(sum.try_into().ok()?) {
        return None;
    }
    let (head, data) = body.split_at_checked(28)?;
    let u32_at = |i: usize| u32::from_le_bytes(head[i..i + 4].try_into().unwrap_or_default());
    let u64_at = |i: usize| u64::from_le_bytes(head[i..i + 8].try_into().unwrap_or_default());
    let rows = outgoing.len();
    if &head[..8] != MAGIC
        || u32_at(8) != CACHE_VERSION
        || u64_at(12) != key
        || u32_at(20) as usize != rows
        || u32_at(24) as usize != cols
        || data.len() != 8 * (3 * rows + 2 * rows * cols)
    {
        return None;
    }
    let values: Vec<f64> = data
        .chunks_exact(8)
        .map(|c| f64::from_bits(u64::from_le_bytes(c.try_into().unwrap_or_default())))
        .collect();
    let (dirs, rest) = values.split_at(3 * rows);
    let stored: Vec<DVec3> = dirs.chunks_exact(3).map(DVec3::from_slice).collect();
    // The hash names the inputs; the directions are compared too, so a collision cannot pass.
    if stored
        .iter()
        .zip(outgoing)
        .any(|(s, o)| s.to_array().map(f64::to_bits) != o.to_array().map(f64::to_bits))
    {
        return None;
    }
    let (a, b) = rest.split_at(rows * cols);
    EnergyTable::from_parts(stored, cols, a.to_vec(), b.to_vec())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sphere::{LobeLayout, srbf};

    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("glint-energy-cache-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    #[test]
    fn a_cached_table_is_the_integrated_table_bit_for_bit() {
        let dir = scratch("roundtrip");
        let lobes = LobeSet::new(LobeLayout::Hemicube { n: 2 }, 33.0).unwrap();
        let (first, source) = table_in(&lobes, Some(&dir));
        assert_eq!(source, Source::Integrated);
        let (again, source) = table_in(&lobes, Some(&dir));
        assert_eq!(source, Source::Memory);
        assert!(Arc::ptr_eq(&first, &again));
        let files: Vec<_> = std::fs::read_dir(&dir).unwrap().flatten().collect();
        assert_eq!(files.len(), 1, "one file, no temporary left");
        let path = files[0].path();
        let outgoing = default_outgoing(&lobes);
        let key = key(&lobes, &outgoing, &EnergyQuadrature::default());
        let read = read(&path, key, &outgoing, lobes.len()).expect("intact");
        let fresh = EnergyTable::with_defaults(&lobes);
        assert_eq!(read.parts(), fresh.parts());
        assert_eq!(read.outgoing(), fresh.outgoing());
        // A new process (memory forgotten) reads it from the disk.
        MEMORY.lock().unwrap().clear();
        let (cached, source) = table_in(&lobes, Some(&dir));
        assert_eq!(source, Source::Disk);
        assert_eq!(cached.parts(), fresh.parts());
        // Every flipped byte, and a truncation, is refused.
        let bytes = std::fs::read(&path).unwrap();
        for i in (0..bytes.len()).step_by(97) {
            let mut bad = bytes.clone();
            bad[i] ^= 0x10;
            assert!(
                decode(&bad, key, &outgoing, lobes.len()).is_none(),
                "byte {i}"
            );
        }
        assert!(decode(&bytes[..bytes.len() - 1], key, &outgoing, lobes.len()).is_none());
        // Another λ is another key and another file.
        let other = LobeSet::new(LobeLayout::Hemicube { n: 2 }, 34.0).unwrap();
        let _ = table_in(&other, Some(&dir));
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 2);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_corrupt_file_is_integrated_again_and_rewritten() {
        let dir = scratch("corrupt");
        let lobes = LobeSet::new(
            LobeLayout::Isotropic { count: 3 },
            srbf::lambda_from_sigma(srbf::PAPER_SIGMA).unwrap() + 0.5,
        )
        .unwrap();
        let outgoing = default_outgoing(&lobes);
        let key = key(&lobes, &outgoing, &EnergyQuadrature::default());
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(file_name(key));
        std::fs::write(&path, b"GLINTENG not a table").unwrap();
        // Not in this process's memory (a λ no other test uses): read from disk, refused.
        let (table, source) = table_in(&lobes, Some(&dir));
        assert_eq!(source, Source::Integrated);
        let reread = read(&path, key, &outgoing, lobes.len()).expect("rewritten");
        assert_eq!(reread.parts(), table.parts());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
