use glint::light::LightSums;
use glint::render::{PhTable, Prt, PrtSettings, Shading, Specular};
use glint::render::table::default_resolution;
use glint::sphere::{DirectionSet, LightTree, LobeLayout, LobeSet, srbf};
use std::time::Instant;
fn main() {
    let bake = std::env::args().nth(1).unwrap();
    let reps: usize = std::env::args().nth(2).map(|s| s.parse().unwrap()).unwrap_or(5);
    let (header, cuts) = glint::bake::file::read(std::path::Path::new(&bake)).unwrap();
    let scene = glint::scene::import(&header.scene_file).unwrap();
    let env = glint::env::load(&header.env_file).unwrap();
    let set = DirectionSet::cube(64).unwrap();
    let tree = LightTree::build(&set);
    let light = LightSums::new(&env, &set, &tree, 0.0);
    let lobes = LobeSet::new(LobeLayout::Isotropic { count: 24 }, srbf::lambda_from_sigma(srbf::PAPER_SIGMA).unwrap()).unwrap();
    let mut c = vec![0.0; lobes.len()];
    (c[0], c[3], c[9]) = (0.8, 0.5, 0.3);
    let table = PhTable::build(&lobes, [&c, &c, &c], default_resolution(lobes.lambda()));
    let shading = Shading { rho_d: [0.5; 3], f0: 0.04, specular: Specular::Table(&table) };
    let prt = Prt::new(&scene.mesh, &cuts, &tree, None, PrtSettings { max_edge_px: 0.0, ..PrtSettings::default() });
    let mut camera = scene.cameras.first().cloned().unwrap_or_else(|| glint::scene::default_camera(&scene.bounds));
    let (w, h) = (640, 480);
    camera.aspect = w as f32 / h as f32;
    let sm = prt.shading_mesh(&camera, w, h);
    let mut best = f64::MAX;
    let mut img = None;
    for _ in 0..reps {
        let t = Instant::now();
        img = Some(prt.render(&light, &camera, w, h, &shading));
        best = best.min(t.elapsed().as_secs_f64());
    }
    let img = img.unwrap();
    let sum: f64 = img.pixels.iter().map(|p| p[1] as f64).sum();
    println!("points {} frame {:.3} s ({:.1} fps) checksum {sum:.6}", sm.points.len(), best, 1.0 / best);
}
