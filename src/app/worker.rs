//! The worker thread that keeps the UI responsive: it loads the inputs, bakes (on a thread of its
//! own, the first view's vertices first), fits, renders preview frames and exports, and reports
//! back as [`Event`]s.
//!
//! Inputs: [`Command`]s from the UI. Outputs: [`Event`]s, each followed by the `wake` callback (the
//! UI asks egui for a repaint there). Invariants: the UI thread never waits on this thread; of
//! several queued frame requests only the newest is rendered; once the bake is complete and
//! nothing has arrived for [`STILL_DELAY`] after a frame, that frame is drawn again as the still
//! frame ([`Engine::render_still`]: what `glint render` draws); a fit of a view whose vertices are
//! not baked yet waits for the whole bake (it would see black, unbaked vertices otherwise); every
//! failure is an [`Event::Error`] line, never a panic of the UI.

use super::AppError;
use super::engine::{Engine, FitResult, PreviewChoice};
use super::state::Document;
use crate::bake::{BakeSettings, Baker, Cuts, PartialBake};
use crate::fit::strokes::ViewSpec;
use crate::render::Image;
use crate::scene::Scene;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::time::Instant;

/// What the UI asks for.
#[derive(Debug, Clone)]
pub enum Command {
    /// A preview frame of a view.
    Render {
        view: ViewSpec,
        size: [u32; 2],
        rotation_deg: f64,
    },
    /// Fit the document and show the result in `view`; `id` comes back in [`Event::Fitted`].
    Fit {
        id: u64,
        doc: Box<Document>,
        view: ViewSpec,
        size: [u32; 2],
    },
    /// Load another environment map.
    SetEnv(PathBuf),
    /// Export the last material into a folder.
    Export { dir: PathBuf, name: String },
    /// Stop the thread.
    Quit,
}

/// What the worker reports.
#[derive(Debug, Clone)]
pub enum Event {
    /// The inputs are loaded: the first view (the scene's first camera) and its orbit parameters.
    Loaded {
        view: ViewSpec,
        size: [u32; 2],
        orbit: [f32; 3],
        vertices: usize,
        triangles: usize,
        device: String,
        anisotropic: bool,
    },
    /// Bake progress (vertices done of the total) and which phase.
    Progress {
        done: usize,
        total: usize,
        phase: &'static str,
    },
    /// The first view is drawn in clay ([`Engine::render_clay`]): painting works from now on (the
    /// fit waits for the first view's bake).
    Paintable { secs_since_start: f64 },
    /// The first view's vertices are baked: fitting works from now on.
    FirstViewReady {
        secs_since_start: f64,
        vertices: usize,
    },
    /// The first view's transfer and the default lobes' energy rows are ready: a stroke's fit there
    /// is only a solve from now on.
    FitPrepared {
        secs_since_start: f64,
        prepare_secs: f64,
    },
    /// Every vertex is baked, and the mesh refined where the bake decided to (`vertices`: the baked
    /// mesh's, after the refinement).
    BakeComplete { bake_secs: f64, vertices: usize },
    /// A preview frame.
    Frame { view: ViewSpec, image: Arc<Image> },
    /// A fit and the frame that shows it.
    Fitted {
        id: u64,
        result: Box<FitResult>,
        image: Arc<Image>,
        view: ViewSpec,
    },
    /// Files written by an export.
    Exported(Vec<PathBuf>),
    /// The environment changed (its path).
    EnvChanged(PathBuf),
    /// Something to tell the user (one line).
    Note(String),
    /// Something went wrong (one line).
    Error(String),
}

enum Msg {
    Cmd(Command),
    /// Cuts so far; with `refined`, the refined mesh (and its tangents) they belong to.
    Cuts {
        cuts: Cuts,
        complete: bool,
        bake_secs: f64,
        refined: Option<(Arc<crate::scene::Mesh>, Option<Vec<glam::Vec4>>)>,
    },
    Progress {
        done: usize,
        total: usize,
        phase: &'static str,
    },
    /// The bake could not finish (its message).
    Failed(String),
}

/// The handle the UI holds.
pub struct Worker {
    tx: Sender<Msg>,
    rx: Receiver<Event>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Worker {
    /// Starts loading `scene` under `env` and baking; `wake` is called after every event.
    pub fn start(
        scene: PathBuf,
        env: PathBuf,
        preview: PreviewChoice,
        wake: Arc<dyn Fn() + Send + Sync>,
    ) -> Self {
        let (tx, rx_msg) = channel::<Msg>();
        let (tx_event, rx) = channel::<Event>();
        let bake_tx = tx.clone();
        let thread = std::thread::Builder::new()
            .name("glint worker".into())
            .spawn(move || {
                let send = |e: Event| {
                    let _ = tx_event.send(e);
                    wake();
                };
                if let Err(e) = run(&scene, &env, preview, &rx_msg, bake_tx, &send) {
                    send(Event::Error(e.to_string()));
                }
            })
            .ok();
        Self { tx, rx, thread }
    }

    /// Queues a command (ignored once the worker has stopped).
    pub fn send(&self, command: Command) {
        let _ = self.tx.send(Msg::Cmd(command));
    }

    /// Events so far, without waiting.
    pub fn poll(&self) -> Vec<Event> {
        self.rx.try_iter().collect()
    }

    /// Waits up to `timeout` for the next event.
    pub fn wait(&self, timeout: std::time::Duration) -> Option<Event> {
        self.rx.recv_timeout(timeout).ok()
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        let _ = self.tx.send(Msg::Cmd(Command::Quit));
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The orbit (azimuth°, elevation°, distance in bounding radii) that reproduces a camera's eye.
fn orbit_of(scene: &Scene, camera: &crate::scene::Camera) -> [f32; 3] {
    let r = scene.bounds.radius().max(1e-12);
    let d = camera.eye() - scene.bounds.centre();
    let len = d.length().max(1e-12);
    [
        d.x.atan2(d.z).to_degrees(),
        (d.y / len).clamp(-1.0, 1.0).asin().to_degrees(),
        len / r,
    ]
}

fn run(
    scene_path: &std::path::Path,
    env_path: &std::path::Path,
    preview: PreviewChoice,
    rx: &Receiver<Msg>,
    bake_tx: Sender<Msg>,
    send: &dyn Fn(Event),
) -> Result<(), AppError> {
    let start = Instant::now();
    let scene = Arc::new(
        crate::scene::import(scene_path)
            .map_err(|e| AppError::Stage(format!("{}: {e}", scene_path.display())))?,
    );
    let env = crate::env::load(env_path)
        .map_err(|e| AppError::Stage(format!("{}: {e}", env_path.display())))?;
    let baker = Baker::new(&scene, &env, BakeSettings::default())
        .map_err(|e| AppError::Stage(e.to_string()))?;
    let decisions = baker.decisions.clone();
    let first_camera = scene
        .cameras
        .first()
        .cloned()
        .unwrap_or_else(|| crate::scene::default_camera(&scene.bounds));
    let size = [first_camera.width.max(1), first_camera.height.max(1)];
    let first_view = ViewSpec::Index(0);
    let mut engine = Engine::new(
        scene.clone(),
        env.clone(),
        env_path.to_path_buf(),
        baker.tangents.clone(),
        decisions.anisotropic,
        decisions.resolution,
        preview,
    )?;
    send(Event::Loaded {
        view: first_view.clone(),
        size,
        orbit: orbit_of(&scene, &first_camera),
        vertices: scene.mesh.positions.len(),
        triangles: scene.mesh.triangles.len(),
        device: engine.device(),
        anisotropic: decisions.anisotropic,
    });
    // Something to paint on before the bake: the first view in clay.
    match engine.render_clay(&first_view, size) {
        Ok(image) => {
            send(Event::Frame {
                view: first_view.clone(),
                image: Arc::new(image),
            });
            send(Event::Paintable {
                secs_since_start: start.elapsed().as_secs_f64(),
            });
        }
        Err(e) => send(Event::Error(e.to_string())),
    }
    // First fit fast: the vertices the first view sees (at its size and at the fit size), then the
    // rest.
    let camera = engine.camera(&first_view, size)?;
    let mut first = crate::raster::visible_vertices(&scene.mesh, &camera, size[0], size[1]);
    first.extend(crate::raster::visible_vertices(
        &scene.mesh,
        &camera,
        (size[0] / 4).max(1),
        (size[1] / 4).max(1),
    ));
    first.sort_unstable();
    first.dedup();
    let cancel = std::sync::atomic::AtomicBool::new(false);
    std::thread::scope(|scope| {
        let (baker, first, cancel) = (&baker, &first, &cancel);
        std::thread::Builder::new()
            .name("glint bake".into())
            .spawn_scoped(scope, move || {
                bake_phases(baker, first, &bake_tx, start, cancel)
            })
            .map_err(|e| AppError::Stage(format!("cannot start the bake thread: {e}")))?;
        let result = serve(
            &mut engine,
            rx,
            send,
            &first_view,
            &first_camera.name,
            size,
            first.len(),
            start,
        );
        cancel.store(true, std::sync::atomic::Ordering::Relaxed);
        result
    })
}

/// How long the view, the light and the material must rest before the worker replaces the preview
/// frame by the still frame ([`Engine::render_still`], what `glint render` draws).
pub const STILL_DELAY: std::time::Duration = std::time::Duration::from_millis(300);

/// The worker's loop over commands and bake results.
#[allow(clippy::too_many_arguments)] // the worker's channels and shared state, each of its own kind
fn serve(
    engine: &mut Engine,
    rx: &Receiver<Msg>,
    send: &dyn Fn(Event),
    first_view: &ViewSpec,
    first_name: &str,
    first_size: [u32; 2],
    first_count: usize,
    start: Instant,
) -> Result<(), AppError> {
    let is_first = |v: &ViewSpec| v == first_view || *v == ViewSpec::Name(first_name.into());
    let mut complete = false;
    let mut first_ready = false;
    let mut waiting_fit: Option<Command> = None;
    // After the first view's cuts, while idle: its transfer and the energy rows, so that the first
    // stroke's fit is only a solve.
    let mut prepare: Option<Document> = None;
    // The last frame drawn, while it is a preview frame: once nothing arrives for STILL_DELAY (and
    // the bake is complete) it is drawn again as the still frame.
    let mut still: Option<(ViewSpec, [u32; 2], f64)> = None;
    let mut pending: Option<Msg> = None;
    loop {
        if prepare.is_none()
            && complete
            && let Some((view, size, rotation_deg)) = still.take()
        {
            match rx.recv_timeout(STILL_DELAY) {
                Ok(m) => {
                    still = Some((view, size, rotation_deg));
                    pending = Some(m);
                }
                Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                    match engine.render_still(&view, size, rotation_deg) {
                        Ok(image) => send(Event::Frame {
                            view,
                            image: Arc::new(image),
                        }),
                        Err(e) => send(Event::Error(e.to_string())),
                    }
                    continue;
                }
                Err(_) => return Ok(()),
            }
        }
        let msg = if let Some(m) = pending.take() {
            m
        } else {
            match prepare.take() {
                Some(doc) => match recv_idle(rx, send, std::time::Duration::from_millis(30)) {
                    Ok(m) => {
                        prepare = Some(doc);
                        m
                    }
                    Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                        match engine.prepare(&doc, first_view, first_size) {
                            Ok(secs) => send(Event::FitPrepared {
                                secs_since_start: start.elapsed().as_secs_f64(),
                                prepare_secs: secs,
                            }),
                            Err(e) => send(Event::Error(e.to_string())),
                        }
                        continue;
                    }
                    Err(_) => return Ok(()),
                },
                None => match rx.recv() {
                    Ok(m) => m,
                    Err(_) => return Ok(()),
                },
            }
        };
        let mut batch = vec![msg];
        batch.extend(rx.try_iter());
        // Of the frame requests in this batch only the newest matters.
        let last_render = batch
            .iter()
            .rposition(|m| matches!(m, Msg::Cmd(Command::Render { .. })));
        for (i, msg) in batch.into_iter().enumerate() {
            match msg {
                Msg::Cmd(Command::Quit) => return Ok(()),
                Msg::Cmd(Command::Render { .. }) if Some(i) != last_render => {}
                Msg::Cmd(Command::Render {
                    view,
                    size,
                    rotation_deg,
                }) => {
                    let frame = if first_ready {
                        engine.render(&view, size, rotation_deg).inspect(|_| {
                            still = Some((view.clone(), size, rotation_deg));
                        })
                    } else {
                        engine.render_clay(&view, size)
                    };
                    match frame {
                        Ok(image) => send(Event::Frame {
                            view,
                            image: Arc::new(image),
                        }),
                        Err(e) => send(Event::Error(e.to_string())),
                    }
                }
                Msg::Cmd(cmd @ Command::Fit { .. }) => {
                    let Command::Fit { doc, .. } = &cmd else {
                        // Cannot fire: this arm's pattern bound `cmd` to a `Command::Fit`.
                        unreachable!()
                    };
                    let needs_all = doc.views.iter().any(|v| !is_first(&v.view));
                    if !first_ready || (needs_all && !complete) {
                        send(Event::Note(
                            "the fit runs once this view's vertices are baked (see the progress)"
                                .into(),
                        ));
                        waiting_fit = Some(cmd);
                    } else {
                        still = fit(engine, cmd, send).or(still);
                    }
                }
                Msg::Cmd(Command::SetEnv(path)) => match engine.set_env(&path) {
                    Ok(()) => send(Event::EnvChanged(path)),
                    Err(e) => send(Event::Error(e.to_string())),
                },
                Msg::Cmd(Command::Export { dir, name }) => match engine.export(&dir, &name) {
                    Ok(files) => send(Event::Exported(files)),
                    Err(e) => send(Event::Error(e.to_string())),
                },
                Msg::Cuts {
                    cuts,
                    complete: all,
                    bake_secs,
                    refined,
                } => {
                    if let Err(e) = engine.set_bake(cuts, refined) {
                        send(Event::Error(e.to_string()));
                        continue;
                    }
                    if !first_ready {
                        first_ready = true;
                        send(Event::FirstViewReady {
                            secs_since_start: start.elapsed().as_secs_f64(),
                            vertices: first_count,
                        });
                        prepare = Some(Document::default());
                    }
                    if all {
                        complete = true;
                        send(Event::BakeComplete {
                            bake_secs,
                            vertices: engine.baked_vertices(),
                        });
                    }
                    let ready = |c: &Command| match c {
                        Command::Fit { doc, .. } => {
                            complete || doc.views.iter().all(|v| is_first(&v.view))
                        }
                        _ => true,
                    };
                    if waiting_fit.as_ref().is_some_and(ready)
                        && let Some(cmd) = waiting_fit.take()
                    {
                        still = fit(engine, cmd, send).or(still);
                    }
                }
                Msg::Progress { done, total, phase } => {
                    send(Event::Progress { done, total, phase })
                }
                Msg::Failed(e) => send(Event::Error(format!("the bake failed: {e}"))),
            }
        }
    }
}

/// The next message, or `Timeout` once `idle` passes without one. The bake's progress, which arrives
/// every few ms while the rest of the mesh is baked, is passed on and does not count: it would
/// otherwise postpone whatever waits for the worker to be idle until the bake ends.
fn recv_idle(
    rx: &Receiver<Msg>,
    send: &dyn Fn(Event),
    idle: std::time::Duration,
) -> Result<Msg, std::sync::mpsc::RecvTimeoutError> {
    let deadline = Instant::now() + idle;
    loop {
        match rx.recv_timeout(deadline.saturating_duration_since(Instant::now()))? {
            Msg::Progress { done, total, phase } => send(Event::Progress { done, total, phase }),
            m => return Ok(m),
        }
    }
}

/// Fits and sends the result with its preview frame; returns the view drawn (for the still frame).
fn fit(
    engine: &mut Engine,
    cmd: Command,
    send: &dyn Fn(Event),
) -> Option<(ViewSpec, [u32; 2], f64)> {
    let Command::Fit {
        id,
        doc,
        view,
        size,
    } = cmd
    else {
        return None;
    };
    let rotation_deg = doc.settings.env_rotation_deg;
    let result = engine.fit(&doc).and_then(|mut r| {
        let t = Instant::now();
        let image = engine.render(&view, size, doc.settings.env_rotation_deg)?;
        r.timings.render_secs = t.elapsed().as_secs_f64();
        Ok((r, image))
    });
    match result {
        Ok((r, image)) => {
            let drawn = (view.clone(), size, rotation_deg);
            send(Event::Fitted {
                id,
                result: Box::new(r),
                image: Arc::new(image),
                view,
            });
            Some(drawn)
        }
        Err(e) => {
            send(Event::Error(e.to_string()));
            None
        }
    }
}

/// Bakes `first` then the remaining vertices (in chunks, so that `cancel` and progress are seen),
/// sending cuts after each phase.
fn bake_phases(
    baker: &Baker,
    first: &[u32],
    tx: &Sender<Msg>,
    start: Instant,
    cancel: &std::sync::atomic::AtomicBool,
) {
    let n = baker.scene().mesh.positions.len();
    let mut state = PartialBake::new(n);
    // Vertices already baked (`state.baked`): those of the first view and the traced neighbours
    // they needed (vertex sampling, decision (f)) are not baked again with the rest, and the result
    // is the CLI's.
    let mut is_first = vec![false; n];
    for &v in first {
        if let Some(f) = is_first.get_mut(v as usize) {
            *f = true;
        }
    }
    let rest: Vec<u32> = (0..n as u32).filter(|&v| !is_first[v as usize]).collect();
    let pool = bake_pool();
    for (phase, vertices) in [("first view", first), ("all vertices", rest.as_slice())] {
        for chunk in vertices.chunks(4096) {
            if cancel.load(std::sync::atomic::Ordering::Relaxed) {
                return;
            }
            let done = state.baked.iter().filter(|&&b| b).count();
            let mut bake = || {
                baker.bake_set(chunk, &mut state, &|k| {
                    let _ = tx.send(Msg::Progress {
                        done: (done + k).min(n),
                        total: n,
                        phase,
                    });
                })
            };
            match &pool {
                Some(pool) => pool.install(bake),
                None => bake(),
            }
        }
        if tx
            .send(Msg::Cuts {
                cuts: state.cuts.clone(),
                complete: false,
                bake_secs: start.elapsed().as_secs_f64(),
                refined: None,
            })
            .is_err()
        {
            return;
        }
    }
    // Decision (e): refine where visibility changes between vertices, then trace the new vertices.
    let _ = tx.send(Msg::Progress {
        done: n,
        total: n,
        phase: "refining",
    });
    let refine = || baker.refine(state, start);
    let bake = match &pool {
        Some(pool) => pool.install(refine),
        None => refine(),
    };
    let refined = if bake.refinement.is_empty() {
        None
    } else {
        match bake.mesh(&baker.scene().mesh) {
            Ok(mesh) => {
                let (_, tangents, _) = crate::bake::decisions::decide_frames(&mesh);
                Some((Arc::new(mesh), tangents))
            }
            // Cannot happen for a refinement made here (split_edges only names existing vertices).
            Err(e) => {
                let _ = tx.send(Msg::Failed(e.to_string()));
                return;
            }
        }
    };
    let _ = tx.send(Msg::Cuts {
        cuts: bake.cuts,
        complete: true,
        bake_secs: start.elapsed().as_secs_f64(),
        refined,
    });
}

/// The background bake's own thread pool, its threads at a lower scheduling priority (nice +10 on
/// Linux), so that the fits, p(h) tables and preview frames the user waits for, which run on
/// rayon's global pool, are neither queued behind bake jobs nor halved by them. (With one shared
/// pool, rayon's workers drain their own queues of bake jobs before jobs injected from the worker
/// thread: on dragon_100k a J = 24 solve took 1.16 s and the table 1.79 s while the bake ran.)
/// `None` (the global pool) when no pool can be made.
fn bake_pool() -> Option<rayon::ThreadPool> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(rayon::current_num_threads())
        .thread_name(|i| format!("glint bake {i}"))
        .start_handler(|_| lower_priority())
        .build()
        .ok()
}

/// Lowers the calling thread's scheduling priority (Linux: `setpriority` on the thread id, which
/// applies to that thread only); a no-op elsewhere or when refused.
fn lower_priority() {
    #[cfg(target_os = "linux")]
    // SAFETY: gettid and setpriority take plain integers and touch no memory of ours; a failure
    // only returns -1, which is ignored (the thread keeps its priority).
    unsafe {
        let tid = libc::gettid();
        let _ = libc::setpriority(libc::PRIO_PROCESS, tid as libc::id_t, 10);
    }
}
