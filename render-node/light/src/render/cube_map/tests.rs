//! Unit tests of the cube-map CPU reference: face coordinates, sampling,
//! and the distance-corrected lookup against an analytic plane.

use super::*;

#[test]
fn face_coordinates_round_trip() {
    for face in 0..CUBE_FACES {
        for (x, y) in [(0, 0), (3, 7), (7, 0), (5, 5)] {
            let d = texel_direction(face, x, y, 8);
            let (f, c) = world_to_face(d);
            assert_eq!(f, face, "{face} {x} {y} -> {d}");
            let ndc = DVec2::new(c.x, c.y) / c.z;
            let tx = ((ndc.x * 0.5 + 0.5) * 8.0).floor() as u32;
            let ty = ((0.5 - ndc.y * 0.5) * 8.0).floor() as u32;
            assert_eq!((tx, ty), (x, y), "face {face}");
        }
    }
}

#[test]
fn sampling_interpolates_between_texel_centres_and_clamps() {
    let mut faces = vec![Image::new(2, 2, Vec3::ZERO); CUBE_FACES];
    faces[4].data = vec![Vec3::ZERO, Vec3::ONE, Vec3::ZERO, Vec3::ONE];
    let map = CubeMap {
        object: 0,
        centre: DVec3::ZERO,
        res: 2,
        faces,
        distance: vec![Image::new(2, 2, NO_SURFACE_DISTANCE); CUBE_FACES],
        state: vec![Image::new(2, 2, PixelState::default()); CUBE_FACES],
    };
    // +z face: right is -x. Straight ahead lies between the columns.
    assert!((map.sample(DVec3::Z).x - 0.5).abs() < 1e-6);
    // Beyond the outer texel centres the value is clamped.
    assert_eq!(map.sample(DVec3::new(0.9, 0.0, 1.0)).x, 0.0);
    assert_eq!(map.sample(DVec3::new(-0.9, 0.0, 1.0)).x, 1.0);
    assert_eq!(map.sample(DVec3::ZERO), Vec3::ZERO);
    assert_eq!(map.sample(DVec3::NAN), Vec3::ZERO);
}

proptest::proptest! {
    #[test]
    fn sampling_any_direction_is_finite(
        x in proptest::num::f64::ANY,
        y in proptest::num::f64::ANY,
        z in proptest::num::f64::ANY,
    ) {
        let map = CubeMap {
            object: 0,
            centre: DVec3::ZERO,
            res: 3,
            faces: (0..CUBE_FACES).map(|f| Image::new(3, 3, Vec3::splat(f as f32))).collect(),
            distance: vec![Image::new(3, 3, 1.0); CUBE_FACES],
            state: vec![Image::new(3, 3, PixelState::default()); CUBE_FACES],
        };
        let v = map.sample(DVec3::new(x, y, z));
        proptest::prop_assert!(v.is_finite() && v.min_element() >= 0.0 && v.max_element() <= 5.0);
    }
}

/// A map at the origin of the plane `z = 1` alone (radiance 0).
fn plane_map(res: u32) -> CubeMap {
    let faces = (0..CUBE_FACES).map(|_| Image::new(res, res, Vec3::ZERO));
    let distance = (0..CUBE_FACES)
        .map(|f| {
            Image::from_fn(res, res, |x, y| {
                let d = texel_direction(f, x, y, res);
                if d.z > 0.0 {
                    (1.0 / d.z) as f32
                } else {
                    NO_SURFACE_DISTANCE
                }
            })
        })
        .collect();
    CubeMap {
        object: 0,
        centre: DVec3::ZERO,
        res,
        faces: faces.collect(),
        distance,
        state: vec![Image::new(res, res, PixelState::default()); CUBE_FACES],
    }
}

#[test]
fn corrected_lookup_finds_the_plane_point_and_infinity_past_it() {
    let map = plane_map(64);
    let p = DVec3::new(0.2, -0.1, 0.3);
    for r in [
        DVec3::new(0.3, 0.2, 1.0),
        DVec3::new(-0.9, 0.4, 0.5),
        DVec3::Z,
    ] {
        let r = r.normalize();
        let hit = p + r * ((1.0 - p.z) / r.z);
        let got = map.reflection_direction(p, r);
        // Well inside one texel (at most 2 / 64 rad).
        let angle = got.normalize().dot(hit.normalize()).clamp(-1.0, 1.0).acos();
        assert!(angle < 0.1 * 2.0 / 64.0, "{r}: {got} vs {hit}: {angle}");
    }
    // Away from the plane nothing is stored: the sentinel distance is
    // the environment at infinity, seen along r.
    let r = DVec3::new(0.3, 0.2, -1.0).normalize();
    let got = map.reflection_direction(p, r).normalize();
    assert!((got - r).length() < 1e-6, "{got} vs {r}");
}

proptest::proptest! {
    #[test]
    fn corrected_lookup_is_finite_for_any_point(
        p in proptest::array::uniform3(proptest::num::f64::ANY),
        r in proptest::array::uniform3(-1.0f64..1.0),
    ) {
        let map = plane_map(4);
        let (p, r) = (DVec3::from_array(p), DVec3::from_array(r));
        let d = map.reflection_direction(p, r);
        proptest::prop_assert!(d.is_finite() || d == r);
        proptest::prop_assert!(map.reflection(p, r).is_finite());
    }
}

#[test]
fn reflection_mirrors_the_normal_component() {
    let r = reflect(DVec3::new(1.0, -1.0, 0.0), DVec3::Y);
    assert_eq!(r, DVec3::new(1.0, 1.0, 0.0));
}
