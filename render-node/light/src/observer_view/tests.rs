//! Tests of the observer view: the mirror lookup, the comparable-figure
//! masks against analytic ground truth.

use super::*;
use crate::render::face::reflected_pixel;
use showcase_proto::{Plane, Rect3};

/// The demo cabinet's front face (deploy/scenes/showcase.toml).
fn face() -> CrtFace {
    CrtFace {
        name: "face-0".into(),
        screen: Rect3 {
            origin: Vec3::new(0.3125, 0.6696, 0.6402),
            right: Vec3::new(-0.625, 0.0, 0.0),
            down: Vec3::new(0.0, -0.25, 0.4330),
        },
        mirror: Plane::from_point_normal(
            Vec3::new(0.0, 0.0, 0.6),
            Vec3::new(0.0, 0.5, 0.866_025_4),
        ),
        width: 64,
        height: 48,
        photometry: showcase_proto::CrtPhotometry::nominal(2.2),
    }
}

/// A 1 m real floor (y = 0, centred on the origin) and a virtual
/// square of half-size `a` floating at height 0.2 above the origin.
fn floor_and_card(a: f32) -> showcase_proto::Showcase {
    use showcase_proto::{Material, Mesh, Object, Showcase, Transform};
    let mut s = Showcase::default();
    let quad = |s: &mut Showcase, h: f32, y: f32| {
        s.add_mesh(Mesh {
            positions: vec![
                Vec3::new(-h, y, -h),
                Vec3::new(h, y, -h),
                Vec3::new(h, y, h),
                Vec3::new(-h, y, h),
            ],
            normals: vec![],
            uvs: vec![],
            triangles: vec![[0, 2, 1], [0, 3, 2]],
        })
    };
    let floor = quad(&mut s, 0.5, 0.0);
    let card = quad(&mut s, a, 0.2);
    for (name, mesh, kind) in [
        ("floor", floor, ObjectKind::Real),
        ("card", card, ObjectKind::Virtual),
    ] {
        s.objects.push(Object {
            name: name.into(),
            mesh,
            material: Material::diffuse(Vec3::splat(0.5)),
            kind,
            transform: Transform::IDENTITY,
        });
    }
    s
}

fn viewer() -> PinholeDevice {
    PinholeDevice::look_at(
        DVec3::new(0.6, 0.9, 0.7),
        DVec3::ZERO,
        DVec3::Y,
        50.0,
        64,
        48,
    )
}

/// Another eye straight above the card shadows the floor under it; with
/// no face, what the viewer sees of that shadow is unfillable, and
/// nothing else is (analytic: the floor point `p` is shadowed when the
/// segment to the eye at (0, 1, 0) crosses the card, `|0.8 p| < a`).
#[test]
fn unfillable_is_the_other_eyes_occlusion_shadow_the_mirror_cannot_show() {
    let a = 0.1;
    let scene = floor_and_card(a as f32);
    let cam = viewer();
    let other = DVec3::new(0.0, 1.0, 0.0);
    let frame = FrameScene::from_parts(scene, &[cam.center(), other]).unwrap();
    let occluders = Occluders::new(&frame).unwrap();
    let view = observer_view(&frame, &occluders, &cam, &[], None).unwrap();
    let rays = DeviceRays::new(&cam).unwrap();
    let (mut inside, mut outside) = (0, 0);
    for y in 0..cam.height {
        for x in 0..cam.width {
            let ray = rays.pixel_ray(x, y).unwrap();
            let got = view.unfillable.get(x, y).copied().unwrap();
            // Where the ray meets the floor and the card's plane.
            let floor = ray.at(-ray.origin.y / ray.direction.y);
            let card = ray.at((0.2 - ray.origin.y) / ray.direction.y);
            let on_card = card.x.abs() < a && card.z.abs() < a;
            let s = (floor.x.abs() * 0.8).max(floor.z.abs() * 0.8);
            if (s - a).abs() < 2e-3 || floor.x.abs().max(floor.z.abs()) > 0.5 {
                continue;
            }
            let expected = !on_card && s < a;
            assert_eq!(got, expected, "pixel ({x}, {y}) floor {floor}");
            if expected {
                inside += 1;
            } else {
                outside += 1;
            }
        }
    }
    assert!(inside > 20 && outside > 1000, "{inside} / {outside}");
    // The viewer's own eye casts no shadow it could see.
    let alone = FrameScene::from_parts(floor_and_card(a as f32), &[cam.center()]).unwrap();
    let occ = Occluders::new(&alone).unwrap();
    let v = observer_view(&alone, &occ, &cam, &[], None).unwrap();
    assert!(v.unfillable.data.iter().all(|u| !u));
}

/// A projector straight above the floor whose edge mask marks the left
/// half of its image: exactly the eye pixels whose floor point falls in
/// that half are marked; a mask of the wrong size is an error.
#[test]
fn projector_edges_are_found_through_the_real_surface() {
    let scene = floor_and_card(0.1);
    let cam = viewer();
    let frame = FrameScene::from_parts(scene, &[]).unwrap();
    let occluders = Occluders::new(&frame).unwrap();
    let projector = Projector {
        name: "p".into(),
        device: PinholeDevice::look_at(
            DVec3::new(0.0, 1.2, 0.0),
            DVec3::ZERO,
            DVec3::Z,
            60.0,
            40,
            30,
        ),
        response: showcase_proto::ProjectorResponse::default(),
    };
    let half = Image::from_fn(40, 30, |x, _| x < 20);
    let marked = projector_edge_pixels(&occluders, &cam, &[(&projector, &half)]).unwrap();
    let (eye, proj) = (
        DeviceRays::new(&cam).unwrap(),
        DeviceRays::new(&projector.device).unwrap(),
    );
    let mut seen = [0, 0];
    for y in 0..cam.height {
        for x in 0..cam.width {
            let ray = eye.pixel_ray(x, y).unwrap();
            let floor = ray.at(-ray.origin.y / ray.direction.y);
            let expected = floor.x.abs().max(floor.z.abs()) < 0.5
                && proj
                    .project(floor)
                    .is_some_and(|p| proj.in_image(p) && p.x < 20.0);
            assert_eq!(marked.get(x, y).copied(), Some(expected), "({x}, {y})");
            seen[usize::from(expected)] += 1;
        }
    }
    assert!(seen[0] > 100 && seen[1] > 100, "{seen:?}");
    let wrong = Image::new(4, 3, true);
    assert!(matches!(
        projector_edge_pixels(&occluders, &cam, &[(&projector, &wrong)]),
        Err(ObserverViewError::SizeMismatch { .. })
    ));
}

#[test]
fn next_to_change_marks_both_sides_of_a_boundary() {
    let m = Image::from_fn(5, 3, |x, _| x >= 3);
    let e = next_to_change(&m);
    for y in 0..3 {
        let row: Vec<bool> = (0..5).map(|x| *e.get(x, y).unwrap()).collect();
        assert_eq!(row, [false, false, true, true, false], "row {y}");
    }
    assert!(
        next_to_change(&Image::new(3, 3, true))
            .data
            .iter()
            .all(|b| !b)
    );
}

/// Every CRT pixel is found again along the eye's line of sight through
/// its reflected position, whatever the eye: the composite reads the
/// face image the way the mirror shows it.
#[test]
fn the_mirror_shows_each_crt_pixel_on_its_line_of_sight() {
    // A linear CRT shows each pixel's drive value as its light.
    let mut face = face();
    face.photometry = showcase_proto::CrtPhotometry::nominal(1.0);
    let (w, h) = (face.width as f32, face.height as f32);
    let code = |x: f32, y: f32| Some(Vec3::new(x / w, y / h, 1.0).as_dvec3());
    let drive = Image::from_fn(face.width, face.height, |x, y| {
        Vec3::new(x as f32 / w, y as f32 / h, 1.0)
    });
    let m = MirrorImage {
        face: &face,
        drive: &drive,
    };
    for eye in [
        DVec3::new(0.0, 0.45, 1.4),
        DVec3::new(0.3, 0.6, 1.2),
        DVec3::new(-0.2, 0.3, 1.6),
    ] {
        for (x, y) in [(0, 0), (63, 47), (10, 40), (32, 24), (50, 5)] {
            let centre = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
            let seen = reflected_pixel(&face, centre);
            let ray = Ray::new(eye, (seen - eye).normalize());
            let got = reflected_radiance(&m, &ray);
            assert_eq!(got, code(x as f32, y as f32), "eye {eye}, pixel ({x}, {y})");
        }
    }
    // The face renderer's projection (mirror_view) draws a world point
    // at the pixel this lookup finds on the eye's ray to that point.
    for eye in [DVec3::new(0.0, 0.45, 1.4), DVec3::new(0.3, 0.6, 1.2)] {
        let view = crate::mirror_view::FaceView::new(&face, eye, 0.01, 10.0).unwrap();
        for world in [
            DVec3::new(-0.10, 0.045, 0.10),
            DVec3::new(0.10, 0.06, -0.10),
            DVec3::new(0.013, 0.021, 0.017),
        ] {
            let px = view.pixel(world, face.width, face.height).unwrap();
            let ray = Ray::new(eye, (world - eye).normalize());
            let got = reflected_radiance(&m, &ray);
            assert_eq!(
                got,
                code(px.x.floor() as f32, px.y.floor() as f32),
                "eye {eye}, world {world}: renderer pixel {px}"
            );
        }
    }
    // A ray that misses the screen's image sees nothing.
    let ray = Ray::new(DVec3::new(0.0, 0.45, 1.4), DVec3::new(0.0, 1.0, 0.0));
    assert_eq!(reflected_radiance(&m, &ray), None);
}

/// The eye sees the real objects and the target through the glass
/// (`T *`), and the CRT's light for the drive values it was sent in the
/// mirror (`R * emit`): against an ideal combiner in front of a nominal
/// CRT, every part scales by exactly its factor.
#[test]
fn the_eye_sees_t_times_real_plus_r_times_the_crts_light() {
    use showcase_proto::{BeamSplitter, CrtPhotometry, CrtResponse};
    let scene = floor_and_card(0.1);
    let cam = PinholeDevice::look_at(
        DVec3::new(0.0, 0.45, 1.4),
        DVec3::new(0.0, 0.1, 0.0),
        DVec3::Y,
        40.0,
        64,
        48,
    );
    let frame = FrameScene::from_parts(scene, &[cam.center()]).unwrap();
    let occluders = Occluders::new(&frame).unwrap();
    let ideal = face();
    let mut real = face();
    real.photometry = CrtPhotometry {
        crt: CrtResponse {
            gamma: Vec3::new(2.4, 2.5, 2.3),
            peak: Vec3::new(2.0, 1.8, 2.2),
            black_level: Vec3::splat(0.004),
        },
        splitter: BeamSplitter {
            transmission: Vec3::new(0.62, 0.6, 0.57),
            reflection: Vec3::new(0.33, 0.35, 0.37),
        },
    };
    let d0 = Vec3::new(0.8, 0.5, 0.3);
    let drive = Image::new(ideal.width, ideal.height, d0);
    let view = |face: &CrtFace| {
        let m = MirrorImage {
            face,
            drive: &drive,
        };
        observer_view(&frame, &occluders, &cam, &[], Some(m)).unwrap()
    };
    let (a, b) = (view(&ideal), view(&real));
    let glass = real.photometry.splitter;
    assert_eq!(b.glass, glass);
    assert_eq!(a.glass, BeamSplitter::IDEAL);
    let per_light = real.photometry.crt.emit(d0) / ideal.photometry.crt.emit(d0);
    let close =
        |x: Vec3, y: Vec3| (x - y).abs().max_element() <= 1e-5 * y.abs().max_element().max(1e-3);
    let mut mirrored = 0;
    for i in 0..a.composite.data.len() {
        assert!(
            close(b.target.data[i], glass.transmission * a.target.data[i]),
            "target {i}"
        );
        assert!(
            close(b.real.data[i], glass.transmission * a.real.data[i]),
            "real {i}"
        );
        let want = glass.reflection * per_light * a.reflected.data[i];
        assert!(
            close(b.reflected.data[i], want),
            "reflected {i}: {} vs {want}",
            b.reflected.data[i]
        );
        assert!(close(
            b.composite.data[i],
            b.real.data[i] + b.reflected.data[i]
        ));
        mirrored += usize::from(a.reflected.data[i].max_element() > 0.0);
    }
    // The eye does look through the mirror at the screen.
    assert!(mirrored > 1000, "{mirrored} pixels see the screen");
    // What the face node sends: its radiance through its own profile, in
    // 8-bit steps, and back through the same device to within a step.
    let radiance = Image::new(4, 1, Vec3::new(0.3, 0.2, 0.1));
    let codes = crt_drive(&real.photometry, &radiance);
    let seen = real.photometry.seen(codes.data[0]);
    assert!(
        (seen - radiance.data[0]).abs().max_element() < 0.01 * 0.3,
        "{seen}"
    );
    for c in 0..3 {
        let code = codes.data[0][c] * 255.0;
        assert!((code - code.round()).abs() < 1e-3, "{code}");
    }
}

/// Another eye straight above the card shadows the floor under it; an
/// eye that sees that shadow through the mirror has it filled by the
/// face, exactly inside the analytic shadow (`|0.8 p| < a`, as in
/// `unfillable_...`), and its seams lie on the shadow's border.
#[test]
fn filled_shadows_and_their_seams_follow_the_other_eyes_shadow() {
    let a = 0.1;
    let scene = floor_and_card(a as f32);
    let cam = PinholeDevice::look_at(
        DVec3::new(0.0, 0.45, 1.4),
        DVec3::new(0.0, 0.0, 0.0),
        DVec3::Y,
        30.0,
        64,
        48,
    );
    let other = DVec3::new(0.0, 1.0, 0.0);
    let frame = FrameScene::from_parts(scene, &[cam.center(), other]).unwrap();
    let occluders = Occluders::new(&frame).unwrap();
    let face = face();
    let drive = Image::new(face.width, face.height, Vec3::ZERO);
    let m = MirrorImage {
        face: &face,
        drive: &drive,
    };
    let view = observer_view(&frame, &occluders, &cam, &[], Some(m)).unwrap();
    let seams = view.seams();
    let rays = DeviceRays::new(&cam).unwrap();
    // Per pixel: `None` on the card, else whether its floor point lies in
    // the analytic shadow, and how far it is from the shadow's border.
    let analytic = Image::from_fn(cam.width, cam.height, |x, y| {
        let ray = rays.pixel_ray(x, y).unwrap();
        let floor = ray.at(-ray.origin.y / ray.direction.y);
        let card = ray.at((0.2 - ray.origin.y) / ray.direction.y);
        if card.x.abs() < a && card.z.abs() < a {
            return None;
        }
        let s = (floor.x.abs() * 0.8).max(floor.z.abs() * 0.8);
        Some((s < a, (s - a).abs()))
    });
    let (mut filled, mut seam) = (0, 0);
    for y in 0..cam.height {
        for x in 0..cam.width {
            let Some((inside, off)) = *analytic.get(x, y).unwrap() else {
                continue;
            };
            let got = *view.filled.get(x, y).unwrap();
            if off > 2e-3 {
                assert_eq!(got, inside, "pixel ({x}, {y})");
            }
            filled += usize::from(got);
            // The nearest pixel on the other side of the analytic border.
            let nearest = (-6i64..=6)
                .flat_map(|dy| (-6i64..=6).map(move |dx| (dx, dy)))
                .filter(|(dx, dy)| {
                    let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                    nx >= 0
                        && ny >= 0
                        && analytic
                            .get(nx as u32, ny as u32)
                            .copied()
                            .flatten()
                            .is_some_and(|(n, _)| n != inside)
                })
                .map(|(dx, dy)| dx.abs().max(dy.abs()))
                .min();
            if *seams.get(x, y).unwrap() {
                seam += 1;
                // Two to four pixels from the border (steps go round
                // the card, so up to one more).
                let n = nearest.unwrap_or(i64::MAX);
                let lo = if off > 0.01 { 2 } else { 1 };
                assert!(
                    (lo..=5).contains(&n),
                    "seam pixel ({x}, {y}) is {n} from the border"
                );
            } else if off > 0.01 && !view.edge.get(x, y).unwrap() {
                // Not a seam: on the border itself or beyond reach.
                let n = nearest.unwrap_or(i64::MAX);
                assert!(
                    n <= 1 || n >= 4,
                    "pixel ({x}, {y}) {n} from the border is no seam"
                );
            }
        }
    }
    assert!(filled > 20 && seam > 10, "{filled} filled, {seam} on seams");
    assert!(view.unfillable.data.iter().all(|u| !u));
}
