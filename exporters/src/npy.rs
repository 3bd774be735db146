//! NumPy `.npy` (format version 1.0) for little-endian f64 and f32 arrays, so anyone can reload a
//! dumped problem (or an exported table) with `numpy.load`.
//!
//! Inputs: a shape and row-major (C-order) f64 or f32 data. Output: the file bytes (or an atomic
//! write). Invariant: the header is padded so the data starts at a multiple of 64 bytes, as the
//! format asks.

use crate::atomic::{AtomicWriteError, write_atomic};
use std::path::Path;

/// The bytes of an `.npy` file holding `data` with `shape` (C order, `<f8`).
pub fn encode_f64(shape: &[usize], data: &[f64]) -> Vec<u8> {
    encode(
        "<f8",
        shape,
        data.iter().flat_map(|v| v.to_le_bytes()),
        data.len() * 8,
    )
}

/// The bytes of an `.npy` file holding `data` with `shape` (C order, `<f4`).
pub fn encode_f32(shape: &[usize], data: &[f32]) -> Vec<u8> {
    encode(
        "<f4",
        shape,
        data.iter().flat_map(|v| v.to_le_bytes()),
        data.len() * 4,
    )
}

fn encode(descr: &str, shape: &[usize], data: impl Iterator<Item = u8>, len: usize) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let shape_text = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut header =
        format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape_text}, }}");
    // magic (6) + version (2) + header length (2) + header + '\n' must be a multiple of 64.
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - unpadded % 64) % 64));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + len);
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out.extend(data);
    out
}

/// Writes an `.npy` file atomically.
pub fn write_f64(path: &Path, shape: &[usize], data: &[f64]) -> Result<(), AtomicWriteError> {
    write_atomic(path, &encode_f64(shape, data))
}

/// Writes an `.npy` file of f32 atomically.
pub fn write_f32(path: &Path, shape: &[usize], data: &[f32]) -> Result<(), AtomicWriteError> {
    write_atomic(path, &encode_f32(shape, data))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_is_aligned_and_data_follows() {
        let bytes = encode_f64(&[2, 3], &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        assert_eq!(&bytes[..6], b"\x93NUMPY");
        let hlen = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        assert_eq!((10 + hlen) % 64, 0);
        let header = std::str::from_utf8(&bytes[10..10 + hlen]).unwrap();
        assert!(header.contains("'shape': (2, 3)") && header.ends_with('\n'));
        assert_eq!(bytes.len(), 10 + hlen + 48);
        assert_eq!(
            f64::from_le_bytes(bytes[10 + hlen + 40..].try_into().unwrap()),
            6.0
        );
        assert!(String::from_utf8_lossy(&encode_f64(&[4], &[0.0; 4])).contains("(4,)"));
        let f = encode_f32(&[1, 2], &[1.5, 2.5]);
        let hlen = u16::from_le_bytes([f[8], f[9]]) as usize;
        assert!(
            String::from_utf8_lossy(&f).contains("'<f4'")
                && (10 + hlen).is_multiple_of(64)
                && f.len() == 10 + hlen + 8
        );
    }
}
