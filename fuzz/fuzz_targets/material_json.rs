//! Fuzz target: arbitrary text as a material file → `glint::fit::material::Material::parse`; an
//! accepted material must build its lobe set and survive a JSON round trip unchanged.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(material) = glint::fit::material::Material::parse(text) else { return };
    let _ = material.lobes();
    // The property under test: whatever parses writes back to JSON that parses. A panic here is a
    // find.
    let again = glint::fit::material::Material::parse(&material.to_json()).expect("a written material parses");
    assert_eq!(again, material);
});
