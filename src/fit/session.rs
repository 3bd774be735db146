//! The fitting context: one type for the CLI's one-shot fit and the app's fit on every stroke.
//!
//! Inputs: [`FitInputs`] (the mesh the cuts belong to, the cuts, the light), the strokes and
//! [`FitSettings`]. Output: a [`FitOutcome`]. What it keeps between fits: the lobes and their
//! energy rows (per layout and σ), each view's transfer (per camera, fit size, rotation, lobes and
//! F0) and the last solve's active sets, which warm-start the next solve. Invariants: a fit from a
//! session equals a fit from a fresh one (the solver is exact from any warm start; a cached
//! transfer is the one that would be computed); the owner calls [`FitSession::forget_transfers`]
//! when the light, the cuts or the mesh change. The current rendering that strokes paint over is
//! the diffuse one (c = 0), as the paper starts; strokes off the object are counted and ignored; no
//! stroke on the object returns the diffuse material and says so.

use super::material::{FitStats, Material};
use super::problem::{ChannelFit, ViewData, solve_rgb_from};
use super::qp::Constraint;
use super::run::{FitError, FitSettings, camera_for, default_layout};
use super::strokes::{ViewSpec, ViewStrokes, targets};
use crate::bake::Cuts;
use crate::brdf::EnergyTable;
use crate::light::LightSums;
use crate::scene::{Camera, Mesh, Scene};
use crate::sphere::{LightTree, LobeLayout, LobeSet, srbf};
use crate::transfer::{Transfer, TransferContext};
use glam::Vec4;
use std::collections::HashMap;
use std::sync::Arc;
use std::time::Instant;

/// What a fit reads besides the strokes and the settings.
#[derive(Clone, Copy)]
pub struct FitInputs<'a> {
    /// The scene: its cameras and bounds (stroke views name them).
    pub scene: &'a Scene,
    /// The mesh the cuts belong to (the bake's refined mesh).
    pub mesh: &'a Mesh,
    pub tangents: Option<&'a [Vec4]>,
    /// Whether the bake decided an anisotropic frame (tangents present).
    pub anisotropic: bool,
    pub cuts: &'a Cuts,
    pub tree: &'a LightTree,
    /// The light sums of the environment at the settings' rotation.
    pub light: &'a LightSums,
}

/// One fitted view.
pub struct FittedView {
    pub camera: Camera,
    pub fit_size: (u32, u32),
    pub transfer: Arc<Transfer>,
    pub target: Vec<[f64; 3]>,
    pub weight: Vec<f64>,
}

/// Everything a fit produced.
pub struct FitOutcome {
    pub material: Material,
    pub views: Vec<FittedView>,
    /// The energy rows the solve was bounded by (`None` with the limit off or nothing to solve).
    pub energy: Option<Arc<EnergyTable>>,
    pub channels: Vec<ChannelFit>,
    /// Seconds spent on transfers (0 when every view's transfer was cached).
    pub transfer_seconds: f64,
}

/// Lobes and energy rows for one layout and σ.
struct LobeCache {
    key: (LobeLayout, u64),
    lobes: LobeSet,
    energy: Option<Arc<EnergyTable>>,
}

/// The fitting context (see the module docs).
#[derive(Default)]
pub struct FitSession {
    lobes: Option<LobeCache>,
    transfers: HashMap<String, Arc<Transfer>>,
    warm: Option<[Vec<Constraint>; 3]>,
}

impl FitSession {
    /// Drops the cached transfers and the warm start (the light, the cuts or the mesh changed).
    pub fn forget_transfers(&mut self) {
        self.transfers.clear();
        self.warm = None;
    }

    /// The lobes for these settings (built once per layout and σ; a change drops the transfers).
    pub fn lobes(
        &mut self,
        settings: &FitSettings,
        anisotropic: bool,
    ) -> Result<&LobeSet, FitError> {
        Ok(&self.lobe_cache(settings, anisotropic)?.lobes)
    }

    fn lobe_cache(
        &mut self,
        settings: &FitSettings,
        anisotropic: bool,
    ) -> Result<&mut LobeCache, FitError> {
        let layout = settings
            .layout
            .unwrap_or_else(|| default_layout(anisotropic));
        if !layout.is_isotropic() && !anisotropic {
            return Err(FitError::Settings(format!(
                "layout {} is anisotropic but the scene has no tangent field",
                layout.name()
            )));
        }
        let key = (layout, settings.sigma.to_bits());
        if self.lobes.as_ref().is_none_or(|l| l.key != key) {
            let lambda = srbf::lambda_from_sigma(settings.sigma)?;
            let lobes = LobeSet::new(layout, lambda)?;
            self.lobes = Some(LobeCache {
                key,
                lobes,
                energy: None,
            });
            self.forget_transfers();
        }
        // Cannot fire: the branch above leaves `lobes` set whenever it was empty or stale.
        Ok(self.lobes.as_mut().expect("set just above"))
    }

    /// The energy rows for these settings' lobes (built once per lobe set and process).
    fn energy(
        &mut self,
        settings: &FitSettings,
        anisotropic: bool,
    ) -> Result<Option<Arc<EnergyTable>>, FitError> {
        if !settings.energy_limit {
            return Ok(None);
        }
        let cache = self.lobe_cache(settings, anisotropic)?;
        Ok(Some(
            cache
                .energy
                .get_or_insert_with(|| super::energy_cache::table(&cache.lobes))
                .clone(),
        ))
    }

    /// The transfer of one view (computed once for its camera, fit size, rotation, lobes and F0).
    fn transfer(
        &mut self,
        inputs: &FitInputs,
        camera: &Camera,
        fit_size: (u32, u32),
        settings: &FitSettings,
    ) -> Result<(Arc<Transfer>, f64), FitError> {
        let key = format!(
            "{:?}|{}|{fit_size:?}|{}|{}|{:?}|{}",
            camera.world_from_camera,
            camera.yfov_rad,
            settings.rotation_rad,
            settings.sigma,
            settings.layout,
            settings.f0
        );
        if let Some(t) = self.transfers.get(&key) {
            return Ok((t.clone(), 0.0));
        }
        let start = Instant::now();
        let lobes = self.lobes(settings, inputs.anisotropic)?;
        let ctx = TransferContext::new(
            inputs.mesh,
            inputs.cuts,
            inputs.tree,
            lobes,
            inputs.tangents,
            None,
        );
        let transfer =
            Arc::new(ctx.compute(inputs.light, camera, fit_size.0, fit_size.1, settings.f0));
        self.transfers.insert(key, transfer.clone());
        Ok((transfer, start.elapsed().as_secs_f64()))
    }

    /// Everything a first stroke in `view` needs besides the solve: lobes, energy rows and the
    /// view's transfer. Returns the seconds it took.
    pub fn prepare(
        &mut self,
        inputs: &FitInputs,
        view: &ViewSpec,
        image_size: [u32; 2],
        settings: &FitSettings,
    ) -> Result<f64, FitError> {
        let start = Instant::now();
        self.energy(settings, inputs.anisotropic)?;
        let camera = camera_for(inputs.scene, view, image_size)?;
        self.transfer(inputs, &camera, fit_size(settings, image_size), settings)?;
        Ok(start.elapsed().as_secs_f64())
    }

    /// Fits the strokes of every view in one solve per channel.
    pub fn fit(
        &mut self,
        inputs: &FitInputs,
        strokes: &[ViewStrokes],
        settings: &FitSettings,
    ) -> Result<FitOutcome, FitError> {
        if settings.rho_d.iter().any(|r| !(0.0..=1.0).contains(r))
            || !(0.0..=1.0).contains(&settings.f0)
        {
            return Err(FitError::Settings(format!(
                "rho_d {:?} and f0 {} must lie in [0, 1]",
                settings.rho_d, settings.f0
            )));
        }
        let j = self.lobes(settings, inputs.anisotropic)?.len();
        let mut views = Vec::new();
        let (mut off_object, mut stroke_count, mut transfer_seconds) = (0, 0, 0.0);
        for v in strokes {
            let camera = camera_for(inputs.scene, &v.view, v.image_size)?;
            let fit_size = fit_size(settings, v.image_size);
            let (transfer, seconds) = self.transfer(inputs, &camera, fit_size, settings)?;
            transfer_seconds += seconds;
            // The rendering strokes paint over: diffuse only.
            let zero = vec![0.0; j];
            let current = transfer.render(settings.rho_d, [&zero, &zero, &zero]);
            let pixels: Vec<(u32, u32)> = transfer.pixels.iter().map(|p| (p.x, p.y)).collect();
            let t = targets(v, &pixels, fit_size, &current);
            off_object += t.off_object.len();
            stroke_count += v.strokes.len();
            views.push(FittedView {
                camera,
                fit_size,
                target: t.target,
                weight: t.weight,
                transfer,
            });
        }
        let mut notes = Vec::new();
        if off_object > 0 {
            notes.push(format!(
                "{off_object} stroke(s) touched no pixel of the object and were ignored"
            ));
        }
        let pixels: usize = views.iter().map(|v| v.transfer.pixels.len()).sum();
        let lobes = &self.lobe_cache(settings, inputs.anisotropic)?.lobes.clone();
        if stroke_count == off_object || pixels == 0 {
            notes.push("no stroke touched the object: the current material (diffuse, no specular lobes) is returned unchanged".into());
            let stats = FitStats {
                pixels,
                views: views.len(),
                energy_limit: settings.energy_limit,
                strokes_off_object: off_object,
                notes,
                ..FitStats::default()
            };
            let zero = vec![0.0; j];
            let material = Material::new(
                lobes,
                settings.sigma,
                [zero.clone(), zero.clone(), zero],
                settings.rho_d,
                settings.f0,
                stats,
            );
            return Ok(FitOutcome {
                material,
                views,
                energy: None,
                channels: Vec::new(),
                transfer_seconds,
            });
        }
        let energy = self.energy(settings, inputs.anisotropic)?;
        let start = Instant::now();
        let data: Vec<ViewData> = views
            .iter()
            .map(|v| ViewData {
                transfer: &v.transfer,
                target: &v.target,
                weight: &v.weight,
            })
            .collect();
        let channels = solve_rgb_from(
            &data,
            energy.as_deref().map(|e| (e, settings.f0)),
            settings.rho_d,
            self.warm.as_ref(),
        )?;
        let solve_seconds = start.elapsed().as_secs_f64();
        self.warm = Some(std::array::from_fn(|c| channels[c].active.clone()));
        let stats = FitStats {
            residual_rms: std::array::from_fn(|c| channels[c].residual_rms),
            active_energy_rows: std::array::from_fn(|c| channels[c].active_energy_rows),
            active_constraints: std::array::from_fn(|c| channels[c].active.len()),
            iterations: std::array::from_fn(|c| channels[c].iterations),
            solve_seconds,
            pixels,
            views: views.len(),
            energy_limit: settings.energy_limit,
            strokes_off_object: off_object,
            notes,
        };
        let coefficients = std::array::from_fn(|c| channels[c].coefficients.clone());
        let material = Material::new(
            lobes,
            settings.sigma,
            coefficients,
            settings.rho_d,
            settings.f0,
            stats,
        );
        Ok(FitOutcome {
            material,
            views,
            energy,
            channels: Vec::from(channels),
            transfer_seconds,
        })
    }
}

/// The fit resolution of a view: the settings', else a quarter of the stroke image in each axis.
fn fit_size(settings: &FitSettings, image_size: [u32; 2]) -> (u32, u32) {
    settings
        .fit_size
        .unwrap_or(((image_size[0] / 4).max(1), (image_size[1] / 4).max(1)))
}
