use pmcodec_lod::measure::*;
use pmcodec_lod::*;
use pmcodec_mesh::gltf_input::RiggedMesh;
fn comps(n: usize, tris: &[[u32;3]]) -> Vec<u32> {
    let mut p: Vec<u32> = (0..n as u32).collect();
    fn f(p: &mut Vec<u32>, mut x: u32) -> u32 { while p[x as usize] != x { x = p[x as usize]; } x }
    for t in tris { let a = f(&mut p, t[0]); for &c in &t[1..] { let b = f(&mut p, c); p[b as usize] = a; } }
    (0..n as u32).map(|v| f(&mut p, v)).collect()
}
fn main() -> anyhow::Result<()> {
    let f = std::env::args().nth(1).unwrap();
    let share: f64 = std::env::args().nth(2).map(|s| s.parse().unwrap()).unwrap_or(0.1);
    let mut rig = RiggedMesh::from_path(std::path::Path::new(&f))?;
    rig.weld();
    let n = rig.triangles.len();
    let t = (n as f64 * share).round() as usize;
    let base = meshopt_baseline(&rig, t);
    let topo = pmcodec_hierarchy::FineTopology::new(rig.positions.len() as u32, &rig.triangles);
    println!("verts {} tris {} edges {} boundary {} instances {} default weights {:?}", rig.positions.len(), rig.triangles.len(), topo.edges.len(), topo.boundary.len(), rig.instances.len(), rig.instances[0].default_weights);
    let c = comps(rig.positions.len(), &rig.triangles);
    let mut full = std::collections::BTreeMap::new();
    for tri in &rig.triangles { *full.entry(c[tri[0] as usize]).or_insert(0) += 1; }
    let mut mo = std::collections::BTreeMap::new();
    for tri in &base.triangles { *mo.entry(c[tri[0] as usize]).or_insert(0) += 1; }
    println!("components {} : full {:?}", full.len(), full.values().collect::<Vec<_>>());
    println!("meshopt {:?}", full.keys().map(|k| mo.get(k).copied().unwrap_or(0)).collect::<Vec<_>>());
    for placement in Placement::ALL {
        let mut opts = LodOptions { placement, ..Default::default() };
        if let Ok(w) = std::env::var("PW") { opts.poses.weights = PoseWeights::parse(&w.split(',').map(String::from).collect::<Vec<_>>())?; }
        if std::env::var("NOW").is_ok() { opts.poses.vertex_weighting = VertexWeighting::None; }
        let chain = build_chain(rig.clone(), &[t], &opts)?;
        let l = &chain.levels[1];
        let mut ours = std::collections::BTreeMap::new();
        for tri in &l.rig.triangles { let id = l.ids[tri[0] as usize].1; *ours.entry(c[id as usize]).or_insert(0) += 1; }
        println!("{:?} {:?}", placement, full.keys().map(|k| ours.get(k).copied().unwrap_or(0)).collect::<Vec<_>>());
        let m = MeasureOptions::default();
        let mut worst = (0.0, 0.0);
        for (a, tt) in frame_times(&rig, 10.0) {
            let d = pmcodec_eval::symmetric_relative(&posed_mesh(&rig, a, tt), &posed_mesh(&l.rig, a, tt), &m.samples)?;
            if d.rms > worst.0 { worst = (d.rms, tt); }
        }
        let r = pmcodec_eval::symmetric_relative(&posed_mesh(&rig, None, 0.0), &posed_mesh(&l.rig, None, 0.0), &m.samples)?;
        println!("   rest {:.4} worst {:?}", r.rms, worst);
        let (a, b) = (posed_mesh(&rig, None, 0.0), posed_mesh(&l.rig, None, 0.0));
        let d1 = pmcodec_eval::one_sided(&a, &b, &m.samples)?; let d2 = pmcodec_eval::one_sided(&b, &a, &m.samples)?;
        println!("   orig->lod {:?} lod->orig {:?} diag {}", d1, d2, a.diagonal());
        if placement == Placement::Endpoint { pmcodec_mesh::write::write_mesh_file(std::path::Path::new("/tmp/lod-ours.obj"), &b)?; pmcodec_mesh::write::write_mesh_file(std::path::Path::new("/tmp/lod-orig.obj"), &a)?; }
    }
    let r = pmcodec_eval::symmetric_relative(&posed_mesh(&rig, None, 0.0), &posed_mesh(&base, None, 0.0), &MeasureOptions::default().samples)?;
    println!("meshopt rest {:.4}", r.rms);
    let (a, b) = (posed_mesh(&rig, None, 0.0), posed_mesh(&base, None, 0.0));
    println!("   orig->mo {:?} mo->orig {:?}", pmcodec_eval::one_sided(&a, &b, &MeasureOptions::default().samples)?, pmcodec_eval::one_sided(&b, &a, &MeasureOptions::default().samples)?);
    pmcodec_mesh::write::write_mesh_file(std::path::Path::new("/tmp/lod-mo.obj"), &b)?;
    Ok(())
}
