use glint::bake::{BakeSettings, Baker};
use glint::light::LightSums;
use glam::DVec3;
use rayon::prelude::*;
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let scene = glint::scene::import(std::path::Path::new(&args[1])).unwrap();
    let env = glint::env::load(std::path::Path::new(&args[2])).unwrap();
    let k: usize = args.get(3).map_or(48, |s| s.parse().unwrap());
    let t0 = std::time::Instant::now();
    let baker = Baker::new(&scene, &env, BakeSettings::default()).unwrap();
    let light = LightSums::new(&env, &baker.set, &baker.tree, 0.0);
    let tree = &baker.tree;
    let nleaves = tree.leaf_count();
    let n = baker.decisions.resolution;
    let p: Vec<f64> = (0..nleaves).map(|l| { let q = light.power(l, l + 1); (q[0] + q[1] + q[2]) / 3.0 }).collect();
    let nv = scene.mesh.positions.len();
    let verts: Vec<usize> = (0..k).map(|i| (i * nv) / k + nv / (2 * k)).collect();
    let cells_deg = [22.5f64, 11.25, 5.625, 2.8125];
    // cells per candidate: largest nodes with count <= cell_leaves
    let cells: Vec<Vec<usize>> = cells_deg.iter().map(|deg| {
        let per = (n as f64 * deg / 90.0).max(1.0); let cl = (per * per).round() as u32;
        let mut out = vec![]; let mut st = vec![0usize];
        while let Some(i) = st.pop() { let nd = tree.nodes()[i]; if nd.count <= cl || nd.is_leaf() { out.push(i) } else { st.push(nd.right as usize); st.push(nd.left as usize); } }
        out }).collect();
    let res: Vec<(Vec<f64>, f64, Vec<f64>)> = verts.par_iter().map(|&v| {
        let (o, nrm) = baker.ray_origin(v).unwrap();
        let o3: glam::Vec3A = o.as_vec3().into();
        let cosw: Vec<f64> = tree.leaf_moments().iter().map(|m| m.dot(nrm).max(0.0)).collect();
        let vis: Vec<f64> = (0..nleaves).map(|l| if cosw[l] > 0.0 && !baker.tracer.occluded(o3, tree.leaf_directions()[l].as_vec3().into()) {1.0} else {0.0}).collect();
        let e_ref: f64 = (0..nleaves).map(|l| vis[l] * p[l] * cosw[l] / tree.leaf_solid_angles()[l]).sum();
        let mut errs = vec![]; let mut l1 = vec![];
        for cs in &cells {
            let mut e = 0.0; let mut mis = 0.0;
            for &c in cs { let nd = tree.nodes()[c]; let r = nd.first as usize..(nd.first + nd.count) as usize;
                let w: f64 = r.clone().map(|l| p[l] * cosw[l] / tree.leaf_solid_angles()[l]).sum();
                if w <= 0.0 { continue }
                let vc = if baker.tracer.occluded(o3, nd.mean_direction.as_vec3().into()) {0.0} else {1.0};
                e += vc * w;
                mis += r.map(|l| (vc - vis[l]).abs() * p[l] * cosw[l] / tree.leaf_solid_angles()[l]).sum::<f64>();
            }
            errs.push(e - e_ref); l1.push(mis);
        }
        (errs, e_ref, l1)
    }).collect();
    let den: f64 = res.iter().map(|r| r.1 * r.1).sum::<f64>();
    let tot: f64 = res.iter().map(|r| r.1).sum::<f64>();
    for (i, d) in cells_deg.iter().enumerate() {
        let num: f64 = res.iter().map(|r| r.0[i] * r.0[i]).sum();
        let mis: f64 = res.iter().map(|r| r.2[i]).sum();
        println!("n={n} cell {d}°: E rel RMS {:.4}  misattributed {:.4}", (num / den).sqrt(), mis / tot);
    }
    println!("{:.2} s", t0.elapsed().as_secs_f64());
}
