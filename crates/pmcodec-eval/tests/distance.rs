//! Surface distance: the closest-point kernel against dense sampling, the BVH against brute
//! force, and the distance figures on meshes whose distance is known in closed form.

use glam::{DVec3, Vec3};
use pmcodec_eval::{
    Distance, EvalError, SampleOptions, SurfaceIndex, one_sided, one_sided_indexed, sample_points, symmetric, symmetric_indexed,
    symmetric_relative, triangle,
};
use pmcodec_mesh::TriMesh;
use proptest::prelude::*;
use std::f32::consts::PI;

// ---------------------------------------------------------------------------------------------
// Meshes

fn square(z: f32) -> TriMesh {
    TriMesh {
        positions: vec![Vec3::new(0.0, 0.0, z), Vec3::new(1.0, 0.0, z), Vec3::new(1.0, 1.0, z), Vec3::new(0.0, 1.0, z)],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// A unit latitude-longitude sphere: a convex polyhedron with its vertices on the unit sphere.
fn uv_sphere(stacks: u32, slices: u32) -> TriMesh {
    let mut positions = vec![Vec3::Z];
    for i in 1..stacks {
        let theta = PI * i as f32 / stacks as f32;
        for j in 0..slices {
            let phi = 2.0 * PI * j as f32 / slices as f32;
            positions.push(Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()));
        }
    }
    positions.push(-Vec3::Z);
    let south = positions.len() as u32 - 1;
    let ring = |i: u32, j: u32| 1 + i * slices + j % slices;
    let mut triangles = Vec::new();
    for j in 0..slices {
        triangles.push([0, ring(0, j), ring(0, j + 1)]);
        for i in 0..stacks - 2 {
            triangles.push([ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)]);
            triangles.push([ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)]);
        }
        triangles.push([ring(stacks - 2, j), south, ring(stacks - 2, j + 1)]);
    }
    TriMesh { positions, triangles }
}

/// A torus of `2 * nu * nv` triangles.
fn torus(nu: u32, nv: u32, big: f32, small: f32) -> TriMesh {
    let mut positions = Vec::new();
    for i in 0..nu {
        let u = 2.0 * PI * i as f32 / nu as f32;
        for j in 0..nv {
            let v = 2.0 * PI * j as f32 / nv as f32;
            let r = big + small * v.cos();
            positions.push(Vec3::new(r * u.cos(), r * u.sin(), small * v.sin()));
        }
    }
    let at = |i: u32, j: u32| (i % nu) * nv + j % nv;
    let mut triangles = Vec::new();
    for i in 0..nu {
        for j in 0..nv {
            triangles.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            triangles.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    TriMesh { positions, triangles }
}

fn transformed(m: &TriMesh, f: impl Fn(Vec3) -> Vec3) -> TriMesh {
    TriMesh { positions: m.positions.iter().map(|&p| f(p)).collect(), triangles: m.triangles.clone() }
}

fn corners(m: &TriMesh, t: usize) -> [Vec3; 3] {
    m.triangles[t].map(|i| m.positions[i as usize])
}

fn brute_force(m: &TriMesh, p: Vec3) -> f32 {
    (0..m.triangles.len()).map(|t| triangle::distance2(p, &corners(m, t))).fold(f64::INFINITY, f64::min) as f32
}

fn close(d: Distance, want: f64, tol: f64) -> bool {
    (d.rms - want).abs() <= tol && (d.max - want).abs() <= tol && (d.mean - want).abs() <= tol
}

fn opts(samples: usize) -> SampleOptions {
    SampleOptions { samples, ..Default::default() }
}

// ---------------------------------------------------------------------------------------------
// Closest point on a triangle

fn coord() -> impl Strategy<Value = f64> {
    -4.0f64..4.0
}

fn point() -> impl Strategy<Value = DVec3> {
    (coord(), coord(), coord()).prop_map(|(x, y, z)| DVec3::new(x, y, z))
}

/// Random triangles, a third of them degenerate: a repeated corner, or a corner on the line
/// through the other two.
fn any_triangle() -> impl Strategy<Value = [DVec3; 3]> {
    (point(), point(), point(), 0u8..6, -1.5f64..2.5).prop_map(|(a, b, c, kind, s)| match kind {
        0 => [a, a, c],
        1 => [a, b, a + (b - a) * s],
        _ => [a, b, c],
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// The exact answer is never beaten by any point of a dense barycentric grid on the
    /// triangle, and the grid comes within its spacing of it; the answer lies on the triangle.
    #[test]
    fn closest_point_matches_dense_sampling(t in any_triangle(), p in point()) {
        let q = triangle::closest_point(p, t);
        let exact = (q - p).length();
        const N: u32 = 120;
        let mut grid_min = f64::INFINITY;
        for i in 0..=N {
            for j in 0..=N - i {
                let (u, v) = (i as f64 / N as f64, j as f64 / N as f64);
                let s = t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v;
                grid_min = grid_min.min((s - p).length());
            }
        }
        let longest = (t[1] - t[0]).length().max((t[2] - t[1]).length()).max((t[0] - t[2]).length());
        prop_assert!(exact <= grid_min + 1e-9, "exact {exact} > grid {grid_min}");
        prop_assert!(grid_min <= exact + longest / N as f64 + 1e-9, "grid {grid_min} far above exact {exact}");
        // q is on the triangle: its own closest point is itself.
        prop_assert!((triangle::closest_point(q, t) - q).length() <= 1e-9 * (1.0 + longest));
    }
}

// ---------------------------------------------------------------------------------------------
// BVH against brute force

fn random_mesh() -> impl Strategy<Value = TriMesh> {
    (3usize..80).prop_flat_map(|n| {
        (
            prop::collection::vec((-10.0f32..10.0, -10.0f32..10.0, -3.0f32..3.0), n),
            // Any corners, repeated ones included: degenerate triangles must be handled too.
            prop::collection::vec([0..n as u32, 0..n as u32, 0..n as u32], 1..150),
        )
            .prop_map(|(p, triangles)| TriMesh { positions: p.into_iter().map(|(x, y, z)| Vec3::new(x, y, z)).collect(), triangles })
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// The BVH's answer is exactly the brute-force minimum, and the triangle it names is at
    /// that distance.
    #[test]
    fn bvh_equals_brute_force(
        mesh in random_mesh(),
        queries in prop::collection::vec((-15.0f32..15.0, -15.0f32..15.0, -8.0f32..8.0), 1..40),
    ) {
        let index = SurfaceIndex::new(&mesh).unwrap();
        prop_assert_eq!(index.triangle_count(), mesh.triangles.len());
        for (x, y, z) in queries {
            let p = Vec3::new(x, y, z);
            let (d2, tri) = index.closest(p);
            prop_assert_eq!(d2, brute_force(&mesh, p), "at {:?}", p);
            prop_assert_eq!(triangle::distance2(p, &corners(&mesh, tri as usize)) as f32, d2);
        }
    }
}

#[test]
fn bvh_equals_brute_force_on_a_large_mesh() {
    // Real sample points (on and near the surface, in sampling order, so the query hints are
    // exercised) against a mesh big enough for a deep tree.
    let fine = torus(60, 40, 1.0, 0.3);
    let coarse = torus(17, 9, 1.0, 0.3);
    let index = SurfaceIndex::new(&coarse).unwrap();
    for p in sample_points(&fine, &opts(400)).unwrap() {
        assert_eq!(index.closest(p).0, brute_force(&coarse, p), "at {p:?}");
    }
}

#[test]
fn closest_names_the_mesh_triangle() {
    let mesh = TriMesh {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(50.0, 0.0, 0.0), Vec3::new(51.0, 0.0, 0.0), Vec3::new(50.0, 1.0, 0.0)],
        triangles: (0..20).map(|_| [0, 1, 2]).chain([[3, 4, 5]]).collect(),
    };
    let index = SurfaceIndex::new(&mesh).unwrap();
    assert_eq!(index.closest(Vec3::new(50.2, 0.2, 2.0)), (4.0, 20));
    assert_eq!(index.closest(Vec3::new(f32::NAN, 0.0, 0.0)).1, u32::MAX);
}

// ---------------------------------------------------------------------------------------------
// Distances with known values

#[test]
fn a_mesh_is_at_zero_from_itself() {
    for m in [square(0.0), uv_sphere(12, 24), torus(30, 12, 2.0, 0.5)] {
        let d = symmetric(&m, &m, &SampleOptions::default()).unwrap();
        assert!(d.max < 1e-6 && d.rms <= d.max && d.mean <= d.rms, "{d:?}");
    }
}

#[test]
fn a_square_shifted_along_its_normal_is_at_the_shift() {
    let (a, b) = (square(0.0), square(0.1));
    let d = symmetric(&a, &b, &SampleOptions::default()).unwrap();
    assert!(close(d, 0.1, 1e-6), "{d:?}");
    assert!(close(one_sided(&a, &b, &SampleOptions::default()).unwrap(), 0.1, 1e-6));
    // A tilted, offset copy of the same situation: the figure is a property of the geometry.
    let rot = glam::Quat::from_euler(glam::EulerRot::XYZ, 0.4, -1.1, 2.0);
    let moved = |z| transformed(&square(z), |p| rot * p + Vec3::new(3.0, -2.0, 5.0));
    let d = symmetric(&moved(0.0), &moved(0.1), &SampleOptions::default()).unwrap();
    assert!(close(d, 0.1, 1e-5), "{d:?}");
}

#[test]
fn a_sphere_and_a_scaled_copy_are_a_shell_apart() {
    // For a convex polyhedron P with vertices on the unit sphere and its copy sP (s > 1), every
    // point of either surface is at least (s-1)·h and at most (s-1) from the other, where h is
    // the smallest distance from the centre to a face plane (see the homothety argument: the
    // distance to sP's face planes exceeds (s-1)·h, the scaled point is within (s-1)|q| <= s-1).
    let inner = uv_sphere(24, 48);
    let s = 1.1f32;
    let outer = transformed(&inner, |p| p * s);
    let h = (0..inner.triangles.len())
        .filter_map(|t| {
            let [a, b, c] = corners(&inner, t).map(Vec3::as_dvec3);
            let n = (b - a).cross(c - a).try_normalize()?;
            Some(n.dot(a).abs())
        })
        .fold(f64::INFINITY, f64::min);
    assert!(h > 0.98 && h < 1.0, "{h}");
    let (lo, hi) = ((s as f64 - 1.0) * h - 1e-6, s as f64 - 1.0 + 1e-6);
    for d in [
        symmetric(&inner, &outer, &SampleOptions::default()).unwrap(),
        one_sided(&inner, &outer, &SampleOptions::default()).unwrap(),
        one_sided(&outer, &inner, &SampleOptions::default()).unwrap(),
    ] {
        for v in [d.rms, d.max, d.mean] {
            assert!((lo..=hi).contains(&v), "{d:?} not in [{lo}, {hi}]");
        }
    }
}

#[test]
fn one_sided_is_one_sided() {
    // A quarter of the unit square lies on it; the square does not lie on the quarter.
    let quarter = transformed(&square(0.0), |p| p * 0.5);
    let o = SampleOptions::default();
    assert!(one_sided(&quarter, &square(0.0), &o).unwrap().max < 1e-7);
    let back = one_sided(&square(0.0), &quarter, &o).unwrap();
    // The far corner (1, 1) is sqrt(0.5) from the quarter's corner (0.5, 0.5), and is a vertex,
    // so it is sampled exactly.
    assert!((back.max - 0.5f64.sqrt()).abs() < 1e-6, "{back:?}");
    let both = symmetric(&quarter, &square(0.0), &o).unwrap();
    assert!(both.max == back.max && both.rms < back.rms && both.mean < back.mean);
}

#[test]
fn relative_is_percent_of_the_reference_diagonal() {
    let o = SampleOptions::default();
    let abs = symmetric(&square(0.0), &square(0.1), &o).unwrap();
    let rel = symmetric_relative(&square(0.0), &square(0.1), &o).unwrap();
    let scale = 100.0 / 2f64.sqrt();
    assert!((rel.rms - abs.rms * scale).abs() < 1e-9 && (rel.max - abs.max * scale).abs() < 1e-9, "{rel:?}");
    assert!((rel.rms - 10.0 / 2f64.sqrt()).abs() < 1e-4, "{rel:?}");
    // Scale-free: the same pair ten times larger gives the same percentages.
    let big = |m: TriMesh| transformed(&m, |p| p * 10.0);
    let rel10 = symmetric_relative(&big(uv_sphere(8, 16)), &big(torus(20, 8, 0.7, 0.2)), &o).unwrap();
    let rel1 = symmetric_relative(&uv_sphere(8, 16), &torus(20, 8, 0.7, 0.2), &o).unwrap();
    assert!((rel10.rms / rel1.rms - 1.0).abs() < 1e-5, "{rel10:?} vs {rel1:?}");
}

// ---------------------------------------------------------------------------------------------
// Determinism, reuse, sampling

#[test]
fn results_do_not_depend_on_threads_or_reuse() {
    let (a, b) = (torus(50, 20, 1.0, 0.25), torus(23, 7, 1.0, 0.25));
    let o = SampleOptions { samples: 10_000, seed: 42 };
    let d = symmetric(&a, &b, &o).unwrap();
    assert_eq!(d, symmetric(&a, &b, &o).unwrap());
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    assert_eq!(d, one.install(|| symmetric(&a, &b, &o)).unwrap());
    let (ia, ib) = (SurfaceIndex::new(&a).unwrap(), SurfaceIndex::new(&b).unwrap());
    assert_eq!(d, symmetric_indexed(&a, &ia, &b, &ib, &o).unwrap());
    assert_eq!(one_sided(&b, &a, &o).unwrap(), one_sided_indexed(&b, &ia, &o).unwrap());
    // Another seed samples other points: close, not identical.
    let other = symmetric(&a, &b, &SampleOptions { seed: 43, ..o }).unwrap();
    assert_ne!(d, other);
    assert!((d.rms / other.rms - 1.0).abs() < 0.02, "{d:?} vs {other:?}");
}

#[test]
fn samples_are_on_the_surface_and_include_used_vertices() {
    let mut m = uv_sphere(10, 20);
    m.positions.push(Vec3::splat(5.0)); // used by no triangle
    let pts = sample_points(&m, &opts(3000)).unwrap();
    assert_eq!(pts.len(), 3000 + m.positions.len() - 1);
    assert!(!pts.contains(&Vec3::splat(5.0)));
    let index = SurfaceIndex::new(&m).unwrap();
    assert!(pts.iter().all(|&p| index.closest(p).0 < 1e-12));
    // Area-uniform: on a sphere-like surface, as many samples above the equator as below.
    let north = pts[..3000].iter().filter(|p| p.z > 0.0).count();
    assert!((1400..=1600).contains(&north), "{north}");
}

/// The benchmark's situation (a ~17k-triangle mesh against a 1.6k-triangle approximation, 20k
/// samples each way) without timing it: it runs, agrees with brute force on a subset, and the
/// figures are ordered as they must be.
#[test]
fn benchmark_sized_case_is_sane() {
    let fine = torus(105, 80, 1.0, 0.3); // 16,800 triangles
    let coarse = torus(40, 20, 1.0, 0.3); // 1,600 triangles
    let d = symmetric(&fine, &coarse, &SampleOptions::default()).unwrap();
    assert!(d.mean > 0.0 && d.mean <= d.rms && d.rms <= d.max, "{d:?}");
    // The coarse torus's chords sag at most r(1 - cos(pi/20)) + R-ish terms below the true
    // surface; the fine one is nearly exact. A few percent of the tube radius at most.
    assert!(d.max < 0.03, "{d:?}");
    let index = SurfaceIndex::new(&fine).unwrap();
    for p in sample_points(&coarse, &opts(200)).unwrap().into_iter().step_by(7) {
        assert_eq!(index.closest(p).0, brute_force(&fine, p));
    }
}

// ---------------------------------------------------------------------------------------------
// Bad input

#[test]
fn bad_meshes_are_errors_not_panics() {
    let o = SampleOptions::default();
    let ok = square(0.0);
    let no_tris = TriMesh { positions: vec![Vec3::ZERO], triangles: vec![] };
    assert_eq!(symmetric(&no_tris, &ok, &o), Err(EvalError::NoTriangles { which: "first" }));
    assert_eq!(symmetric(&ok, &TriMesh::default(), &o), Err(EvalError::NoTriangles { which: "second" }));
    assert_eq!(one_sided(&ok, &no_tris, &o), Err(EvalError::NoTriangles { which: "target" }));
    assert!(SurfaceIndex::new(&no_tris).is_err());

    let mut nan = square(0.0);
    nan.positions[2].y = f32::NAN;
    let err = symmetric_relative(&ok, &nan, &o).unwrap_err();
    assert_eq!(err, EvalError::NonFinite { which: "approximation", vertex: 2 });
    assert!(err.to_string().contains("NaN") && err.to_string().contains("vertex 2"), "{err}");
    let mut inf = square(0.0);
    inf.positions[1].z = f32::INFINITY;
    assert_eq!(one_sided(&inf, &ok, &o), Err(EvalError::NonFinite { which: "source", vertex: 1 }));
    let mut huge = square(0.0);
    huge.positions[3].x = 1e30;
    assert_eq!(symmetric(&ok, &huge, &o), Err(EvalError::OutOfRange { which: "second", vertex: 3 }));

    let mut bad_index = square(0.0);
    bad_index.triangles[1][2] = 9;
    assert_eq!(symmetric(&bad_index, &ok, &o), Err(EvalError::BadIndex { which: "first", triangle: 1, index: 9, vertex_count: 4 }));

    let point = TriMesh { positions: vec![Vec3::ONE], triangles: vec![[0, 0, 0]] };
    assert_eq!(symmetric_relative(&point, &ok, &o), Err(EvalError::ZeroExtent { which: "reference" }));
}

#[test]
fn degenerate_meshes_are_measured() {
    let o = SampleOptions::default();
    // Zero area everywhere: only its vertices are sampled, and the surface is its segments.
    let line = TriMesh { positions: vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0], triangles: vec![[0, 1, 2], [1, 1, 1]] };
    // Its vertices are 0.5, 0.5 and sqrt(1.25) from the square half a unit above.
    let d = one_sided(&line, &square(0.5), &o).unwrap();
    let far = 1.25f64.sqrt();
    assert!((d.max - far).abs() < 1e-6, "{d:?}");
    assert!((d.mean - (1.0 + far) / 3.0).abs() < 1e-6, "{d:?}");
    assert!((d.rms - (1.75f64 / 3.0).sqrt()).abs() < 1e-6, "{d:?}");
    let above = transformed(&line, |p| p + Vec3::new(0.0, 0.5, 1.0));
    let d = one_sided(&square(0.0), &above, &o).unwrap();
    assert!(d.max.is_finite() && d.mean >= 1.0 - 1e-6, "{d:?}");
    let d = symmetric(&line, &line, &o).unwrap();
    assert_eq!(d.max, 0.0);
    // Zero samples asked: the vertices alone still give a figure.
    let d = symmetric(&square(0.0), &square(0.1), &SampleOptions { samples: 0, seed: 1 }).unwrap();
    assert!(close(d, 0.1, 1e-6), "{d:?}");
}

#[test]
fn a_hinted_walk_finds_the_closest_distance_from_any_hint() {
    // The hint only bounds the walk: a far, a near, an out-of-range or no hint give the same
    // distance as the unhinted query.
    let m = torus(40, 16, 1.0, 0.3);
    let index = SurfaceIndex::new(&m).unwrap();
    let n = m.triangles.len() as u32;
    let mut rng = pmcodec_eval::SplitMix64::new(3);
    let mut unit = || (rng.next_u64() >> 11) as f32 / (1u64 << 53) as f32;
    for i in 0..2000u32 {
        let p = Vec3::new(unit() * 3.0 - 1.5, unit() * 3.0 - 1.5, unit() - 0.5);
        let (d, t) = index.closest(p);
        for hint in [0, i % n, (i * 7919) % n, t, n, u32::MAX] {
            let (dh, th) = index.closest_near(p, hint);
            assert_eq!(dh, d, "point {p} hint {hint}");
            assert!(th < n);
        }
    }
}
