//! The p(h) EXR: header attributes and pixels read back by the `exr` crate (independent of our
//! hand-written encoder) and by the OpenEXR Python package (`exporters/python/check_exr.py`).
//!
//! Inputs: the fixture material. Outputs: pass/fail. Invariants: the Python half fails in CI when
//! Python/OpenEXR is missing.

mod common;

use common::*;
use glint_exporters::exr::{AttrValue, ph_exr_file_name};
use glint_exporters::{
    Exporter, ExrExporter, PARAMETERISATION, read_ph_exr, read_ph_exr_attributes,
};
use std::process::Command;

#[test]
fn exr_reads_back_exactly_with_its_attributes() {
    let dir = temp_dir("exr-rust");
    let desc = material("table", 32);
    let files = ExrExporter.export(&desc, None, &dir).unwrap();
    assert_eq!(files, [dir.join("table_ph.exr")]);
    let table = read_ph_exr(&files[0]).unwrap();
    assert_eq!(table.resolution, 32);
    assert!(
        table
            .texels
            .iter()
            .zip(&desc.table.texels)
            .all(|(a, b)| a.map(f32::to_bits) == b.map(f32::to_bits)),
        "pixels differ"
    );
    let a = read_ph_exr_attributes(&files[0]).unwrap();
    assert_eq!(a["glint.model"], AttrValue::Text("dbrdf-srbf".into()));
    assert_eq!(a["glint.version"], AttrValue::Int(1));
    assert_eq!(a["glint.lambda"], AttrValue::Double(desc.lambda));
    assert_eq!(a["glint.sigma"], AttrValue::Double(desc.sigma));
    assert_eq!(a["glint.f0"], AttrValue::Double(desc.f0));
    assert_eq!(a["glint.rho_d"], AttrValue::Vec3(desc.rho_d));
    assert_eq!(a["glint.layout"], AttrValue::Text(desc.layout.clone()));
    assert_eq!(
        a["glint.frame_convention"],
        AttrValue::Text(desc.frame_convention.clone())
    );
    assert_eq!(
        a["glint.brdf_convention"],
        AttrValue::Text(desc.brdf_convention.clone())
    );
    let AttrValue::Text(p) = &a["glint.parameterisation"] else {
        panic!("{:?}", a["glint.parameterisation"])
    };
    assert!(
        p.starts_with(PARAMETERISATION) && p.contains("px = (a+b)/2"),
        "{p}"
    );
    let AttrValue::Text(prov) = &a["glint.provenance"] else {
        panic!()
    };
    let prov: serde_json::Value = serde_json::from_str(prov).unwrap();
    assert_eq!(prov["tool"], "glint 0.1.0 (test)");
    // The non-ASCII provenance value is escaped, not dropped.
    assert_eq!(
        serde_json::from_value::<std::collections::BTreeMap<String, String>>(prov).unwrap(),
        desc.provenance
    );
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn exr_reader_refuses_garbage() {
    let dir = temp_dir("exr-bad");
    let path = dir.join("bad_ph.exr");
    std::fs::write(&path, b"not an exr").unwrap();
    let m = read_ph_exr(&path).unwrap_err().to_string();
    assert!(m.contains("bad_ph.exr") && !m.contains('\n'), "{m}");
    assert!(read_ph_exr(&dir.join("missing.exr")).is_err());
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn exr_matches_openexr_python() {
    let Some(py) = python("OpenEXR, numpy") else {
        return;
    };
    let dir = temp_dir("exr-py");
    // Non-square-friendly sizes and the default resolution.
    for (name, r) in [
        ("odd", 7u32),
        ("default", glint_exporters::DEFAULT_TABLE_RESOLUTION),
    ] {
        let desc = material(name, r);
        ExrExporter.export(&desc, None, &dir).unwrap();
        let flat: Vec<f32> = desc.table.texels.iter().flatten().copied().collect();
        let npy = dir.join(format!("{name}.npy"));
        glint_exporters::npy::write_f32(&npy, &[r as usize, r as usize, 3], &flat).unwrap();
        let script = workspace().join("exporters/python/check_exr.py");
        let exr = dir.join(ph_exr_file_name(name));
        let (ok, out, err) = run(Command::new(&py).arg(&script).arg(&exr).arg(&npy));
        assert!(ok, "check_exr.py failed:\n{out}\n{err}");
        eprintln!("{}", out.trim());
        // And it notices a difference.
        let mut other = flat.clone();
        other[3 * (r as usize) + 1] += 1e-3;
        glint_exporters::npy::write_f32(&npy, &[r as usize, r as usize, 3], &other).unwrap();
        let (ok, out, _) = run(Command::new(&py).arg(&script).arg(&exr).arg(&npy));
        assert!(
            !ok && out.contains("pixel (x=0, y=1) channel G") && out.trim().lines().count() == 1,
            "{out}"
        );
    }
    std::fs::remove_dir_all(dir).unwrap();
}
