//! The painting app, headless: egui_kittest drives the real UI (pointer events on the viewport),
//! the worker bakes, fits and renders on the wgpu preview (lavapipe without a GPU). Checks that a
//! left-drag becomes a stroke in the view's pixels, that the fit runs on release, that the painted
//! region of the preview gets brighter (and pixels far from the stroke do not rise more than it),
//! and that Ctrl+Z takes the highlight away again; that painting works on the clay view before the
//! bake, the fit following once the view is baked. Also `glint app --replay --screenshot` end to
//! end.
//!
//! Needs a Vulkan or GL adapter; without one the tests skip with a message, except under CI=true
//! where they fail.

use crate::common;
use egui::{Event, Modifiers, PointerButton, Pos2};
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use glint::app::{AppOptions, GlintApp};
use glint::fit::strokes::polyline_distance;
use glint::render::Image;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// A short stroke on the bunny's flank (default view, view pixels) where the studio's brightest
/// light reflects: the spot a lobe at h = n lights most (found by rendering that lobe alone, `glint
/// render`). A highlight painted where a light can reflect is one an isotropic BRDF can make
/// without lighting up the rest; one painted where no light reflects (the sample stroke across the
/// back) can only be approached by broad lobes that brighten every pixel alike (measured with
/// `glint fit`: far pixels rose 0.027 for 0.030 in the painted band).
const STROKE: [[f64; 2]; 2] = [[409.0, 262.0], [418.0, 272.0]];
const RADIUS_PX: f64 = 10.0;
const KEEP_WEIGHT: f64 = 1.0;
/// About 2.6× the diffuse radiance there.
const INTENSITY: f32 = 0.6;

fn gpu_or_skip() -> bool {
    match glint::gpu::GpuContext::headless() {
        Ok(_) => true,
        Err(e) if std::env::var("CI").is_ok_and(|v| v == "true") => {
            panic!("CI=true but no GPU adapter: {e}")
        }
        Err(e) => {
            eprintln!("skipping: no GPU adapter ({e})");
            false
        }
    }
}

fn options() -> AppOptions {
    let samples = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("samples");
    AppOptions {
        scene: samples.join("bunny.glb"),
        env: samples.join("studio_1k.exr"),
        autosave: None,
        session: None,
        replay: Vec::new(),
        preview: Default::default(),
    }
}

type AppHarness<'a> = Harness<'a, Option<GlintApp>>;

fn app<'h>(h: &'h AppHarness) -> &'h GlintApp {
    h.state().as_ref().expect("made on the first step")
}

/// The app in a harness of `size` points, made on the first step.
fn harness<'a>(opts: AppOptions, size: [f32; 2]) -> AppHarness<'a> {
    Harness::builder()
        .with_size(size)
        .with_max_steps(1_000_000)
        .build_ui_state(
            move |ui, state: &mut Option<GlintApp>| {
                state
                    .get_or_insert_with(|| GlintApp::new(opts.clone(), ui.ctx()))
                    .show(ui);
            },
            None,
        )
}

/// Steps the UI (with real time passing for the worker) until `done` or the timeout.
fn step_until(h: &mut AppHarness, what: &str, timeout_secs: f64, done: impl Fn(&GlintApp) -> bool) {
    let start = Instant::now();
    loop {
        h.step();
        if h.state().as_ref().is_some_and(&done) {
            return;
        }
        if let Some(e) = h.state().as_ref().and_then(|a| {
            a.messages()
                .iter()
                .find(|m| m.starts_with("error"))
                .cloned()
        }) {
            panic!("waiting for {what}: {e}");
        }
        assert!(
            start.elapsed().as_secs_f64() < timeout_secs,
            "timed out waiting for {what}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Mean luminance over the pixels covered in both images that `select` picks (by view position).
fn mean_luminance(a: &Image, b: &Image, select: impl Fn([f64; 2]) -> bool) -> (f64, f64, usize) {
    let lum = |p: [f32; 3]| 0.2126 * p[0] as f64 + 0.7152 * p[1] as f64 + 0.0722 * p[2] as f64;
    let (mut sa, mut sb, mut n) = (0.0, 0.0, 0);
    for y in 0..a.height {
        for x in 0..a.width {
            let k = (y * a.width + x) as usize;
            if a.covered[k] && b.covered[k] && select([x as f64 + 0.5, y as f64 + 0.5]) {
                sa += lum(a.pixels[k]);
                sb += lum(b.pixels[k]);
                n += 1;
            }
        }
    }
    (sa / n.max(1) as f64, sb / n.max(1) as f64, n)
}

/// Left-drags along `points` (view pixels) on screen.
fn drag(h: &mut AppHarness, points: &[[f64; 2]]) {
    let screen: Vec<Pos2> = points
        .iter()
        .map(|p| app(h).view_to_screen(*p).unwrap())
        .collect();
    let mut path = Vec::new();
    for w in screen.windows(2) {
        for k in 0..8 {
            path.push(w[0] + (w[1] - w[0]) * (k as f32 / 8.0));
        }
    }
    path.push(*screen.last().unwrap());
    h.event(Event::PointerMoved(path[0]));
    h.step();
    h.event(Event::PointerButton {
        pos: path[0],
        button: PointerButton::Primary,
        pressed: true,
        modifiers: Modifiers::NONE,
    });
    h.step();
    for p in &path[1..] {
        h.event(Event::PointerMoved(*p));
        h.step();
    }
    h.event(Event::PointerButton {
        pos: *path.last().unwrap(),
        button: PointerButton::Primary,
        pressed: false,
        modifiers: Modifiers::NONE,
    });
}

/// On dragon_100k the first view takes about a second to bake (release) and the clay view half
/// that: a stroke painted on the clay view is kept, its fit waits, and runs once the view's
/// vertices are baked.
#[test]
fn painting_on_the_clay_view_before_the_bake_fits_once_baked() {
    if !gpu_or_skip() {
        return;
    }
    let opts = AppOptions {
        scene: common::assets().join("glb/dragon_100k.glb"),
        env: PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("samples/courtyard_1k.exr"),
        ..options()
    };
    let mut h = harness(opts, [1200.0, 700.0]);
    step_until(&mut h, "the clay view", 120.0, |a| {
        a.paintable() && a.preview_image().is_some()
    });
    let a = app(&h);
    assert!(
        !a.ready(),
        "the first view was baked before the clay view was shown"
    );
    // The clay view: grey, drawn from the mesh alone.
    let clay = a.preview_image().unwrap().clone();
    let covered: Vec<[f32; 3]> = (0..clay.pixels.len())
        .filter(|&k| clay.covered[k])
        .map(|k| clay.pixels[k])
        .collect();
    assert!(covered.len() > 10_000, "{} covered pixels", covered.len());
    assert!(
        covered
            .iter()
            .all(|p| p[0] == p[1] && p[1] == p[2] && p[0] >= 0.1)
    );
    // The stroke through the middle of the view.
    let size = [clay.width as f64, clay.height as f64];
    let stroke = [
        [0.45 * size[0], 0.5 * size[1]],
        [0.55 * size[0], 0.5 * size[1]],
    ];
    drag(&mut h, &stroke);
    step_until(&mut h, "the fit after the bake", 300.0, |a| {
        a.fits_done() >= 1 && !a.fit_pending()
    });
    let a = app(&h);
    assert_eq!(a.document().stroke_count(), 1);
    let (paint, baked) = (
        a.painting_possible_secs().unwrap(),
        a.first_fit_possible_secs().unwrap(),
    );
    assert!(
        paint < baked,
        "painting {paint} s, first view baked {baked} s"
    );
    assert!(a.last_fit().unwrap().result.material.fit.pixels > 100);
    eprintln!("painting possible {paint:.2} s, first view baked {baked:.2} s after launch");
}

#[test]
fn painting_a_stroke_fits_and_brightens_the_painted_region_only() {
    if !gpu_or_skip() {
        return;
    }
    let opts = options();
    let mut h = harness(opts, [1200.0, 700.0]);
    step_until(
        &mut h,
        "the first view's bake, frame and prepared fit",
        300.0,
        |a| a.ready() && a.preview_image().is_some() && a.first_fit_ready_secs().is_some(),
    );
    // Unpainted pixels weigh as much as painted ones: the user's lever for "leave the rest alone".
    let mut settings = app(&h).document().settings.clone();
    settings.keep_weight = KEEP_WEIGHT;
    settings.brush.intensity = INTENSITY;
    h.state_mut().as_mut().unwrap().set_settings(settings);
    step_until(&mut h, "the fit of the new settings", 120.0, |a| {
        a.fits_done() >= 1 && !a.fit_pending()
    });
    let before: Arc<Image> = app(&h).preview_image().unwrap().clone();
    assert_eq!((before.width, before.height), (640, 480));

    // Left-drag along the stroke on screen.
    drag(&mut h, &STROKE);
    let released = Instant::now();
    step_until(&mut h, "the fit", 120.0, |a| {
        a.fits_done() >= 2 && !a.fit_pending()
    });
    eprintln!(
        "stroke release → preview: {:.3} s (app's own figure {:.3} s)",
        released.elapsed().as_secs_f64(),
        app(&h).last_fit().unwrap().release_to_preview_secs
    );

    // The stroke arrived in view pixels, where it was drawn (within a pixel of the mapping).
    let doc = app(&h).document();
    assert_eq!(doc.stroke_count(), 1);
    let points = &doc.views[0].strokes[0].points;
    assert!(points.len() >= 4, "{points:?}");
    for p in points {
        assert!(
            polyline_distance(*p, &STROKE) < 1.5,
            "{p:?} is off the drawn stroke"
        );
    }
    // The fit ran and found specular lobes.
    let fit = app(&h).last_fit().unwrap();
    let m = &fit.result.material;
    assert!(m.fit.pixels > 1000, "{} fit pixels", m.fit.pixels);
    assert!(
        m.coefficients.iter().flatten().any(|c| *c > 0.0),
        "no specular lobe was fitted"
    );
    let after: Arc<Image> = app(&h).preview_image().unwrap().clone();

    let painted = |p: [f64; 2]| polyline_distance(p, &STROKE) < RADIUS_PX;
    let far = |p: [f64; 2]| polyline_distance(p, &STROKE) > 6.0 * RADIUS_PX;
    let (lum_before, lum_after, n) = mean_luminance(&before, &after, painted);
    eprintln!("painted region ({n} px): mean luminance {lum_before:.4} → {lum_after:.4}");
    let (far_before, far_after, n_far) = mean_luminance(&before, &after, far);
    eprintln!("far pixels ({n_far} px): mean luminance {far_before:.4} → {far_after:.4}");
    assert!(n_far > 2000, "{n_far} far pixels");
    assert!(n > 300, "{n} painted pixels");
    assert!(
        lum_after > 1.15 * lum_before,
        "painted region not brighter: {lum_before} → {lum_after}"
    );

    // Far pixels change little: the fitted lobe also lights the few other spots where a light
    // reflects at the same half-vector angle, which moves the mean of the far pixels by a small
    // fraction of the painted rise.
    let rise_painted = lum_after - lum_before;
    let change_far = (far_after - far_before).abs();
    eprintln!(
        "far change / painted rise = {:.3}",
        change_far / rise_painted
    );
    assert!(
        change_far < 0.2 * rise_painted,
        "far pixels changed {change_far} vs the painted rise {rise_painted}"
    );
    assert!(
        change_far < 0.1 * far_before,
        "far pixels changed {change_far} from {far_before}"
    );

    // Ctrl+Z takes the stroke back: the preview returns to the diffuse frame.
    h.key_press_modifiers(Modifiers::COMMAND, egui::Key::Z);
    step_until(&mut h, "the fit after undo", 120.0, |a| {
        a.fits_done() >= 3 && !a.fit_pending()
    });
    assert_eq!(app(&h).document().stroke_count(), 0);
    let undone: Arc<Image> = app(&h).preview_image().unwrap().clone();
    let (_, lum_undone, _) = mean_luminance(&before, &undone, painted);
    assert!(
        (lum_undone - lum_before).abs() < 0.02 * lum_before,
        "undo left {lum_undone} vs {lum_before}"
    );

    // The rest of the bake, refined (decision (e)): the engine switches to the refined mesh, and a
    // redo fits the stroke again there: the painted region brightens as it did on the first view's
    // cuts.
    step_until(&mut h, "the whole bake with its refinement", 300.0, |a| {
        a.bake_complete()
    });
    let note = app(&h)
        .messages()
        .iter()
        .find(|m| m.starts_with("bake complete"))
        .cloned()
        .unwrap_or_default();
    let vertices: usize = note
        .split('(')
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0);
    assert!(
        vertices > 1839,
        "the bunny's bake refines its 1,839 vertices: {note}"
    );
    h.key_press_modifiers(Modifiers::COMMAND | Modifiers::SHIFT, egui::Key::Z);
    step_until(
        &mut h,
        "the fit after redo, on the refined mesh",
        120.0,
        |a| a.fits_done() >= 4 && !a.fit_pending(),
    );
    assert_eq!(app(&h).document().stroke_count(), 1);
    let redone: Arc<Image> = app(&h).preview_image().unwrap().clone();
    let (_, lum_redone, _) = mean_luminance(&before, &redone, painted);
    eprintln!(
        "after the refined bake: painted region {lum_before:.4} → {lum_redone:.4} (first fit {lum_after:.4})"
    );
    assert!(
        lum_redone > 1.15 * lum_before,
        "painted region after the refined bake: {lum_before} → {lum_redone}"
    );
    assert!(
        (lum_redone - lum_after).abs() < 0.1 * lum_after,
        "refined {lum_redone} vs first {lum_after}"
    );
}

#[test]
fn replay_screenshot_writes_the_app_after_the_fit() {
    if !gpu_or_skip() {
        return;
    }
    let dir = std::env::temp_dir().join(format!("glint-app-replay-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("app.png");
    let root = env!("CARGO_MANIFEST_DIR");
    let o = crate::glint_command!()
        .current_dir(root)
        .args([
            "app",
            "samples/bunny.glb",
            "--env",
            "samples/studio_1k.exr",
            "--replay",
            "samples/strokes/bunny-highlight.json",
            "--size",
            "1000x600",
            "--screenshot",
        ])
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(stdout.contains("release → preview"), "{stdout}");
    let img = image::open(&out).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (1000, 600));
    // Not a blank frame: the preview and the panel give many distinct colours.
    let distinct: std::collections::HashSet<[u8; 3]> = img.pixels().map(|p| p.0).collect();
    assert!(distinct.len() > 500, "{} distinct colours", distinct.len());
    // Bad input: one line, non-zero exit, no panic.
    let o = crate::glint_command!()
        .current_dir(root)
        .args(["app", "no-such.glb", "--screenshot"])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// At the app's default window size (1280×760) the side panel is taller than the window: the mouse
/// wheel over it scrolls it until the export row, below the window's edge at first, is on screen.
#[test]
fn side_panel_scrolls_to_the_export_row_at_the_default_window_size() {
    if !gpu_or_skip() {
        return;
    }
    let opts = options();
    let (w, h_px) = (1280.0, 760.0);
    let mut h = harness(opts, [w, h_px]);
    step_until(
        &mut h,
        "the first view's bake, frame and prepared fit",
        300.0,
        |a| a.ready() && a.preview_image().is_some() && a.first_fit_ready_secs().is_some(),
    );
    // A fit puts the p(h) image into the panel (what pushed the export row off the window).
    let settings = app(&h).document().settings.clone();
    h.state_mut().as_mut().unwrap().set_settings(settings);
    step_until(&mut h, "a fit", 120.0, |a| {
        a.fits_done() >= 1 && !a.fit_pending()
    });
    for _ in 0..10 {
        h.step();
    }
    let before = h.get_by_label("Export").rect();
    eprintln!(
        "export button at y {:.0}..{:.0} in a {h_px}-point window",
        before.min.y, before.max.y
    );
    let panel = Pos2::new(w - 80.0, 0.5 * h_px);
    h.event(Event::PointerMoved(panel));
    h.step();
    for _ in 0..40 {
        h.event(Event::MouseWheel {
            unit: egui::MouseWheelUnit::Point,
            delta: egui::vec2(0.0, -60.0),
            phase: egui::TouchPhase::Move,
            source: egui::MouseWheelSource::Unknown,
            modifiers: Modifiers::NONE,
        });
        h.step();
    }
    for _ in 0..30 {
        h.step();
    }
    let after = h.get_by_label("Export").rect();
    eprintln!("after scrolling: y {:.0}..{:.0}", after.min.y, after.max.y);
    assert!(
        after.min.y >= 0.0 && after.max.y <= h_px,
        "the export row is not reachable: {after:?} (window height {h_px})"
    );
    assert!(
        before.max.y > h_px,
        "the export row fits without scrolling now ({before:?}): this test no longer checks the scrolling"
    );
    assert!(
        after.min.y < before.min.y,
        "the wheel did not scroll the panel: {before:?} -> {after:?}"
    );
}

/// The still frame: once the view rests, the app's engine draws what `glint render` draws (the PRT
/// frame at its default settings, shaded per pixel) in place of the vertex-shaded preview. On the
/// bunny under the studio map with the sample strokes fitted, 160×120: the still frame equals a PRT
/// frame rendered directly with the default settings (light sums from scratch rather than from the
/// engine's kept source: 1e-6), and differs from the preview (the preview's own error, which the
/// still frame removes; `cargo bench --bench render` measures both against Monte Carlo).
#[test]
fn the_still_frame_is_the_render_commands_frame() {
    use glint::render::{Prt, PrtSettings, Shading, Specular};
    if !gpu_or_skip() {
        return;
    }
    let samples = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("samples");
    let (scene_path, env_path) = (samples.join("bunny.glb"), samples.join("studio_1k.exr"));
    let scene = glint::scene::import(&scene_path).unwrap();
    let env = glint::env::load(&env_path).unwrap();
    let baker = glint::bake::Baker::new(&scene, &env, Default::default()).unwrap();
    let bake = baker.bake_refined(None, &|_| {});
    let (set, tree) = (baker.set.clone(), baker.tree.clone());
    drop(baker);
    let baked = bake.scene(&scene).unwrap();
    let (_, tangents, _) = glint::bake::decisions::decide_frames(&baked.mesh);
    let refined =
        (!bake.refinement.is_empty()).then(|| (Arc::new(baked.mesh.clone()), tangents.clone()));
    let (_, scene_tangents, _) = glint::bake::decisions::decide_frames(&scene.mesh);
    let mut engine = glint::app::engine::Engine::new(
        Arc::new(scene),
        env.clone(),
        env_path,
        scene_tangents,
        bake.decisions.anisotropic,
        bake.decisions.resolution,
        glint::app::PreviewChoice::Cpu,
    )
    .unwrap();
    engine.set_bake(bake.cuts.clone(), refined).unwrap();
    let doc = glint::app::state::Document {
        views: glint::fit::strokes::parse(
            &std::fs::read_to_string(samples.join("strokes/bunny-highlight.json")).unwrap(),
        )
        .unwrap(),
        ..Default::default()
    };
    let fitted = engine.fit(&doc).unwrap();
    let view = doc.views[0].view.clone();
    let size = [160, 120];
    let preview = engine.render(&view, size, 0.0).unwrap();
    let still = engine.render_still(&view, size, 0.0).unwrap();
    // The same frame from the renderer directly, as `glint render` draws it.
    let m = &fitted.material;
    let lobes = m.lobes().unwrap();
    let c = &m.coefficients;
    let table = glint::render::PhPyramid::build(
        &lobes,
        [&c[0], &c[1], &c[2]],
        glint::render::table::default_resolution(lobes.lambda()),
    );
    let light = glint::light::LightSums::new(&env, &set, &tree, 0.0);
    let prt = Prt::new(
        &baked.mesh,
        &bake.cuts,
        &tree,
        tangents.as_deref(),
        PrtSettings::default(),
    );
    let camera = engine.camera(&view, size).unwrap();
    let mut direct = prt.render(
        &light,
        &camera,
        size[0],
        size[1],
        &Shading {
            rho_d: m.rho_d,
            f0: m.f0,
            specular: Specular::Table(&table),
        },
    );
    direct.fill_background(&env, 0.0, &camera);
    let mask = vec![true; (size[0] * size[1]) as usize];
    let (still_vs_direct, pixels) = glint::accuracy::masked_rel_rmse(&still, &direct, &mask);
    let (preview_vs_still, _) = glint::accuracy::masked_rel_rmse(&preview, &still, &mask);
    println!(
        "still frame vs the render command's frame {still_vs_direct:.2e} over {pixels} pixels; preview vs still {:.2} %",
        100.0 * preview_vs_still
    );
    assert!(pixels > 1000, "{pixels} object pixels");
    assert!(
        still_vs_direct < 1e-4,
        "the still frame is not glint render's frame: {still_vs_direct}"
    );
    assert!(
        preview_vs_still > 5e-3,
        "the still frame changed nothing ({preview_vs_still})"
    );
}
