//! Shadow rays against ground truth: the Cornell box's intensity image
//! against analytic cos/r^2 with an independent shadow test, and
//! visibility without acne or leaks.

use super::*;

/// Parameter interval of the segment `a + s (b - a)`, `s` in `[0, 1]`,
/// inside the convex polytope `n . x <= d + margin` (Cyrus-Beck).
fn clip_segment(a: DVec3, b: DVec3, planes: &[(DVec3, f64)], margin: f64) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    let d = b - a;
    for &(n, off) in planes {
        let (num, den) = (off + margin - n.dot(a), n.dot(d));
        if den == 0.0 {
            if num < 0.0 {
                return None;
            }
        } else if den > 0.0 {
            hi = hi.min(num / den);
        } else {
            lo = lo.max(num / den);
        }
    }
    (lo <= hi).then_some((lo, hi))
}

/// Outward face planes of a convex block mesh, plus the floor `y >= 0`.
fn block_planes(mesh: &Mesh) -> Vec<(DVec3, f64)> {
    let mut planes: Vec<(DVec3, f64)> = mesh
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| mesh.positions[i as usize].as_dvec3());
            let n = (b - a).cross(c - a).normalize();
            (n, n.dot(a))
        })
        .collect();
    planes.push((-DVec3::Y, 0.0));
    planes
}

#[test]
fn cornell_box_intensity_image_matches_analytic_cos_over_r2_with_true_shadows() {
    let scene = cornell_box();
    let geometry = SceneGeometry::build(&scene, &ObjectFilter::Real).unwrap();
    let eye = DVec3::new(0.278, 0.273, -0.8);
    let camera = PinholeDevice::look_at(eye, eye + DVec3::Z, DVec3::Y, 39.3077, 96, 96);
    let projector = PinholeDevice::look_at(
        DVec3::new(0.40, 0.50, 0.15),
        DVec3::new(0.25, 0.0, 0.35),
        DVec3::Y,
        100.0,
        256,
        192,
    );
    let (c_p, eta) = (Vec3::new(1.0, 0.5, 0.25), 2.5);
    let light = IntensityLight::projector(&projector, c_p, eta).unwrap();
    let camera_rays = DeviceRays::new(&camera).unwrap();
    let image = render_intensity(&geometry, &camera_rays, &light, &ObjectFilter::All);
    let floor = scene.object_index("floor").unwrap() as u32;
    let blocks: Vec<Vec<(DVec3, f64)>> = ["short_block", "tall_block"]
        .iter()
        .map(|name| {
            let o = &scene.objects[scene.object_index(name).unwrap()];
            block_planes(scene.mesh(&o.mesh).unwrap())
        })
        .collect();
    let centre = projector.center();
    let (mut lit, mut shadowed, mut outside) = (0, 0, 0);
    for y in 0..camera.height {
        for x in 0..camera.width {
            let value = *image.intensity.get(x, y).unwrap();
            assert!(value.is_finite() && value.min_element() >= 0.0);
            let Some(sample) = image.surface.get(x, y).unwrap() else {
                assert_eq!(value, Vec3::ZERO, "background must be 0");
                continue;
            };
            if sample.object != floor {
                continue;
            }
            // The floor point from the analytic ray/plane intersection.
            let d = camera.unproject(DVec2::new(x as f64 + 0.5, y as f64 + 0.5));
            let p = eye + (-eye.y / d.y) * d;
            assert!(
                (sample.point - p).length() < 1e-9,
                "{} vs {p}",
                sample.point
            );
            assert!((sample.normal - DVec3::Y).length() < 1e-12);
            assert!((sample.phi - (-d.y).acos()).abs() < 1e-9);
            let in_image = projector
                .project(p)
                .is_some_and(|q| q.x >= 0.0 && q.y >= 0.0 && q.x < 256.0 && q.y < 192.0);
            if !in_image {
                assert_eq!(value, Vec3::ZERO, "outside the projector's image must be 0");
                outside += 1;
                continue;
            }
            let inside = |margin: f64| {
                blocks
                    .iter()
                    .filter_map(|b| clip_segment(p, centre, b, margin))
                    .count()
            };
            let blocked_clearly = blocks
                .iter()
                .filter_map(|b| clip_segment(p, centre, b, -1e-4))
                .any(|(lo, hi)| hi - lo > 1e-6);
            if blocked_clearly {
                assert_eq!(value, Vec3::ZERO, "pixel ({x}, {y}) is in a block's shadow");
                assert!(!sample.lit);
                shadowed += 1;
            } else if inside(1e-4) == 0 {
                let l = centre - p;
                let expected = (l.y / l.length() / l.length_squared()) * eta * c_p.as_dvec3();
                let rel = (value.as_dvec3() - expected).length() / expected.length();
                assert!(rel < 1e-6, "pixel ({x}, {y}): {value} vs {expected}");
                assert!(sample.lit);
                lit += 1;
            }
        }
    }
    assert!(
        lit > 500 && shadowed > 50 && outside > 20,
        "lit {lit}, shadowed {shadowed}, outside {outside}"
    );

    // Piecewise: shading only the floor changes nothing on it and blanks the rest.
    let floor_only = render_intensity(
        &geometry,
        &camera_rays,
        &light,
        &ObjectFilter::Indices(vec![floor as usize]),
    );
    for (i, s) in image.surface.data.iter().enumerate() {
        if s.is_some_and(|s| s.object == floor) {
            assert_eq!(floor_only.intensity.data[i], image.intensity.data[i]);
        } else {
            assert_eq!(floor_only.intensity.data[i], Vec3::ZERO);
            assert!(floor_only.surface.data[i].is_none());
        }
    }
}

#[test]
fn visibility_has_no_acne_and_no_leaks() {
    let scene = cornell_box();
    let geometry = SceneGeometry::build(&scene, &ObjectFilter::Real).unwrap();
    let eps = geometry.epsilon();
    assert!(eps > 0.0 && eps < 1e-8);
    // Floor points right against the back wall see a point light inside the
    // box even at grazing incidence (no acne) ...
    for k in 0..50 {
        let x = 0.35 + 0.002 * k as f64;
        let p = DVec3::new(x, 0.0, 0.5592 - 1e-7);
        assert!(geometry.visible(p, DVec3::Y, DVec3::new(0.5, 1e-4, 0.45), false));
        assert!(geometry.visible(p, DVec3::Y, DVec3::new(x, 0.5, 0.5592 - 1e-6), false));
        // ... and never a light just behind the back wall (no leaks).
        assert!(!geometry.visible(p, DVec3::Y, DVec3::new(x, 0.3, 0.5592 + 1e-6), false));
        assert!(!geometry.visible(p, DVec3::Y, DVec3::new(x, 1e-6, 0.6), false));
    }
    // Surface to surface: floor to ceiling is open, floor under a block to
    // the ceiling is not.
    // The mesh is f32: the ceiling is at 0.5488 rounded to f32.
    let ceiling = DVec3::new(0.45, f64::from(0.5488f32), 0.1);
    assert!(geometry.visible(DVec3::new(0.45, 0.0, 0.1), DVec3::Y, ceiling, true));
    assert!(!geometry.visible(DVec3::new(0.18, 0.0, 0.16), DVec3::Y, ceiling, true));
    assert!(!geometry.visible(DVec3::NAN, DVec3::Y, ceiling, true));
    // Point-to-device: a camera sees what is in front of it, in its image
    // and unoccluded.
    let eye = DVec3::new(0.278, 0.273, -0.8);
    let camera = DeviceRays::new(&PinholeDevice::look_at(
        eye,
        eye + DVec3::Z,
        DVec3::Y,
        39.3077,
        64,
        64,
    ))
    .unwrap();
    let back_z = f64::from(0.5592f32);
    let back = DVec3::new(0.278, 0.273, back_z);
    assert!(camera.sees(&geometry, DVec3::new(0.278, 0.45, back_z), -DVec3::Z));
    assert!(
        !camera.sees(&geometry, back, DVec3::Z),
        "camera behind the surface"
    );
    assert!(
        !camera.sees(&geometry, DVec3::new(0.2, 0.1, 0.16), -DVec3::Z),
        "inside the short block"
    );
    assert!(
        !camera.sees(&geometry, eye - DVec3::Z, DVec3::Z),
        "behind the camera"
    );
}
