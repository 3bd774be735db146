//! Fuzz target: arbitrary text as a stroke file → `glint::fit::strokes::parse`; accepted files are
//! then applied to a small pixel grid (eq. 23 targets and weights), which must stay finite.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(views) = glint::fit::strokes::parse(text) else { return };
    for view in &views {
        let pixels: Vec<(u32, u32)> = (0..4).flat_map(|y| (0..4).map(move |x| (x, y))).collect();
        let current = vec![[0.25f64; 3]; pixels.len()];
        let t = glint::fit::strokes::targets(view, &pixels, (4, 4), &current);
        assert!(t.target.iter().flatten().all(|x| x.is_finite()), "{t:?}");
        assert!(t.weight.iter().all(|w| w.is_finite() && *w >= 0.0), "{t:?}");
    }
});
