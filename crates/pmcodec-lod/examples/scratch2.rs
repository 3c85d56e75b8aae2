use pmcodec_lod::measure::*;
use pmcodec_lod::*;
use pmcodec_mesh::gltf_input::*;
use glam::Vec3;
fn main() -> anyhow::Result<()> {
    let mut rig = RiggedMesh::default();
    rig.nodes = vec![NodeTransform::default()];
    rig.parents = vec![None];
    let (nr, na) = (20usize, 30usize);
    for r in 1..nr { let th = std::f32::consts::PI * r as f32 / nr as f32;
        for a in 0..na { let ph = std::f32::consts::TAU * a as f32 / na as f32;
            rig.positions.push(Vec3::new(th.sin()*ph.cos()*(1.0+0.5*(3.0*ph).sin()), th.cos()*2.0, th.sin()*ph.sin())); } }
    let top = rig.positions.len() as u32; rig.positions.push(Vec3::new(0.0,2.0,0.0));
    let bot = top+1; rig.positions.push(Vec3::new(0.0,-2.0,0.0));
    let at = |r: usize, a: usize| (r*na + a%na) as u32;
    for r in 0..nr-2 { for a in 0..na { rig.triangles.push([at(r,a),at(r,a+1),at(r+1,a)]); rig.triangles.push([at(r,a+1),at(r+1,a+1),at(r+1,a)]); } }
    for a in 0..na { rig.triangles.push([top, at(0,a+1), at(0,a)]); rig.triangles.push([bot, at(nr-2,a), at(nr-2,a+1)]); }
    let n = rig.positions.len();
    rig.joints = vec![[0;4]; n]; rig.weights = vec![[0.0;4]; n];
    rig.source = (0..n as u32).map(|i| pmcodec_mesh::SourceVertex{primitive:0,index:i}).collect();
    rig.instances.push(MeshInstance{node:0,mesh:0,skin:None,vertices:0..n,morph_targets:vec![],default_weights:vec![]});
    let t = rig.triangles.len()/10;
    let base = meshopt_baseline(&rig, t);
    let s = MeasureOptions::default().samples;
    let r = pmcodec_eval::symmetric_relative(&posed_mesh(&rig, None, 0.0), &posed_mesh(&base, None, 0.0), &s)?;
    println!("tris {} -> {t}: meshopt {:.4} ({} tris)", rig.triangles.len(), r.rms, base.triangles.len());
    for placement in Placement::ALL {
        let chain = build_chain(rig.clone(), &[t], &LodOptions { placement, ..Default::default() })?;
        let l = &chain.levels[1].rig;
        let r = pmcodec_eval::symmetric_relative(&posed_mesh(&rig, None, 0.0), &posed_mesh(l, None, 0.0), &s)?;
        println!("{placement:?} {:.4} ({} tris)", r.rms, l.triangles.len());
    }
    Ok(())
}
