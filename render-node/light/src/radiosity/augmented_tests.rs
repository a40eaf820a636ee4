//! Augmented-radiosity checks against closed forms: the gathered B2 in a
//! furnace (every vertex, corners included, sees the enclosure at total
//! form factor 1) and the clip-compensated B1 pass, whose B3 must be B0
//! wherever B2 was not clipped.

use super::tests::add_quad;
use super::*;
use crate::ObjectFilter;
use glam::{DVec3, Vec3};
use showcase_proto::{Light, Material, ObjectKind, Showcase};

fn quad(s: &mut Showcase, name: &str, c: Vec3, u: Vec3, v: Vec3, rho: f32, kind: ObjectKind) {
    add_quad(s, name, c, u, v, Material::diffuse(Vec3::splat(rho)), kind);
}

fn mesh(s: &Showcase, area: f64, depth: u32) -> (RadiosityMesh, SceneGeometry, SceneGeometry) {
    let all = SceneGeometry::build(s, &ObjectFilter::All).unwrap();
    let real = SceneGeometry::build(s, &ObjectFilter::Real).unwrap();
    let m = RadiosityMesh::build(
        s,
        &all,
        &MeshOptions {
            max_patch_area: area,
            element_depth: depth,
            ..MeshOptions::default()
        },
    )
    .unwrap();
    (m, all, real)
}

#[test]
fn gathered_b2_in_a_furnace_is_b0_times_one_minus_rho_at_every_vertex() {
    // A closed real cube, uniform B0 on every wall (and a glowing wall, to
    // show the gather's emission is not mistaken for interreflection): at
    // any inner point the walls subtend total form factor 1, so the real
    // interreflection is rho * B0 and B2 = (1 - rho) B0 exactly, at the
    // corners and edges too.
    let rho = 0.6;
    let mut s = Showcase::default();
    let (x, y, z) = (Vec3::X, Vec3::Y, Vec3::Z);
    let k = ObjectKind::Real;
    quad(&mut s, "floor", Vec3::ZERO, z, x, rho, k);
    quad(&mut s, "top", y, x, z, rho, k);
    quad(&mut s, "left", Vec3::ZERO, y, z, rho, k);
    quad(&mut s, "right", x, z, y, rho, k);
    quad(&mut s, "back", z, y, x, rho, k);
    quad(&mut s, "front", Vec3::ZERO, x, y, rho, k);
    s.objects[1].material.emission = Vec3::splat(0.5);
    let (m, _, real) = mesh(&s, 0.13, 1);
    let b0 = DVec3::new(1.0, 2.0, 3.0);
    let solution = AugmentedSolution {
        b0: vec![b0; m.elements.len()],
        b1: vec![b0 * (1.0 + rho as f64); m.elements.len()],
        b2: vec![b0 * (1.0 - rho as f64); m.elements.len()],
        b3: vec![b0; m.elements.len()],
        clipped_elements: 0,
        real_elements: m.elements.len(),
        b1_b0_deviation_rgb: [0.0; 3],
        b3_b0_deviation_rgb: [0.0; 3],
        shots: [0; 3],
        b0_residual: 0.0,
    };
    let b2 = gathered_b2_vertices(&m, &real, &solution, &GatherOptions::default());
    assert_eq!(b2.len(), m.vertices.len());
    let want = b0 * (1.0 - rho as f64);
    let worst = b2
        .iter()
        .map(|v| ((*v - want) / want).abs().max_element())
        .fold(0.0, f64::max);
    assert!(worst < 2e-3, "worst relative error {worst}");
}

/// A real floor and back wall (an L), a virtual point light above the
/// back of the floor and a virtual screen standing across the floor: in B0
/// the front of the floor lies in the screen's shadow and sees neither the
/// light nor the back wall, but the real room has no screen, so the back
/// wall lights it more than B0 asks for there.
fn screened_scene() -> (Showcase, Vec<Light>) {
    let mut s = Showcase::default();
    let (x, y, z) = (Vec3::X, Vec3::Y, Vec3::Z);
    quad(&mut s, "floor", Vec3::ZERO, z, x, 0.8, ObjectKind::Real);
    quad(&mut s, "back", z, y, x, 0.8, ObjectKind::Real);
    quad(
        &mut s,
        "screen",
        0.5 * z,
        0.6 * y,
        x,
        0.1,
        ObjectKind::Virtual,
    );
    let light = Light::Point {
        position: Vec3::new(0.5, 0.9, 0.8),
        intensity: Vec3::splat(2.0),
    };
    (s, vec![light])
}

#[test]
fn clip_compensated_b3_is_b0_wherever_b2_is_not_clipped() {
    let (s, lights) = screened_scene();
    let (m, all, real) = mesh(&s, 0.02, 0);
    let o = SolveOptions {
        threshold: 1e-6,
        method: FormFactorMethod::RayCast,
        ..SolveOptions::default()
    };
    let deviation = |pass: B1Pass| {
        let a = augmented_radiosity_with(&m, &all, &real, &lights, &o, pass).unwrap();
        let mut worst: f64 = 0.0;
        let mut scale: f64 = 0.0;
        for (((e, b0), b1), b3) in m.elements.iter().zip(&a.b0).zip(&a.b1).zip(&a.b3) {
            if e.real {
                scale = scale.max(b0.max_element());
                if (2.0 * *b0 - *b1).min_element() >= 0.0 {
                    worst = worst.max((*b3 - *b0).abs().max_element());
                } else {
                    // Clipped: the real room ends brighter than B0 there.
                    assert!((*b3 - *b0).min_element() > -1e-6 * scale, "{b3} < {b0}");
                }
            }
        }
        (a.clipped_elements, worst / scale)
    };
    let (clipped, compensated) = deviation(B1Pass::ClipCompensated);
    let (one_clipped, one_bounce) = deviation(B1Pass::OneBounce);
    assert!(clipped > 0 && one_clipped > 0, "{clipped} {one_clipped}");
    // B3 = (I - K)^-1 B2 is B0 on the unclipped elements to the solve's
    // tolerance; with plain one bounce the clipped floor's surplus light
    // reaches them.
    assert!(compensated < 1e-3, "{compensated}");
    assert!(
        one_bounce > 10.0 * compensated,
        "{one_bounce} vs {compensated}"
    );
}
