//! Integration tests: scene files. The shared Cornell box and bunny load
//! with the right parts, counts and materials; glTF and calibration files
//! load; every shipped scene validates; every kind of bad input is an
//! `Err` naming the file and the field or line; no input panics.

use glam::{DVec3, Vec3};
use showcase_master::scene_file::{SceneError, load_scene, load_scene_str};
use showcase_proto::{Light, ObjectKind, Showcase, Validate};
use std::path::{Path, PathBuf};

mod errors;
mod robustness;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn fixtures() -> PathBuf {
    root().join("tests/fixtures/scenes")
}

/// Load `text` as if it were `case.toml` in the repository root.
fn load_root(text: &str) -> Result<Showcase, SceneError> {
    load_scene_str(text, &root(), "case.toml")
}

/// Load `text` as if it were `case.toml` in the fixtures folder.
fn load_fixture(text: &str) -> Result<Showcase, SceneError> {
    load_scene_str(text, &fixtures(), "case.toml")
}

/// World-space bounds of an object.
fn world_bounds(s: &Showcase, name: &str) -> (Vec3, Vec3) {
    let o = &s.objects[s
        .object_index(name)
        .unwrap_or_else(|| panic!("no object {name}"))];
    let m = o.transform.matrix();
    let mesh = s.mesh(&o.mesh).unwrap();
    mesh.positions
        .iter()
        .map(|p| m.transform_point3(*p))
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p), hi.max(p))
        })
}

const CORNELL: &str = "../shared/data/cornell-box.obj";
const BUNNY: &str = "../shared/data/bunny.obj";

#[test]
fn cornell_box_loads_with_every_part_and_its_mtl_values() {
    let s = load_root(&format!(
        "name = \"c\"\n[[object]]\nname = \"box\"\nmesh = \"{CORNELL}\"\nkind = \"real\"\n"
    ))
    .unwrap();
    let names: Vec<&str> = s.objects.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "box/floor",
            "box/ceiling",
            "box/back",
            "box/right_green",
            "box/left_red",
            "box/short_block",
            "box/tall_block",
            "box/light",
        ]
    );
    let tris = |n: &str| {
        s.mesh(&s.objects[s.object_index(n).unwrap()].mesh)
            .unwrap()
            .triangles
            .len()
    };
    assert_eq!(tris("box/floor"), 2);
    assert_eq!(tris("box/short_block"), 10);
    assert_eq!(tris("box/tall_block"), 10);
    assert_eq!(tris("box/light"), 2);
    let mat = |n: &str| &s.objects[s.object_index(n).unwrap()].material;
    assert_eq!(mat("box/left_red").albedo, Vec3::new(0.63, 0.065, 0.05));
    assert_eq!(mat("box/right_green").albedo, Vec3::new(0.14, 0.45, 0.091));
    assert_eq!(mat("box/floor").albedo, Vec3::new(0.725, 0.71, 0.68));
    assert_eq!(mat("box/light").emission, Vec3::new(17.0, 12.0, 4.0));
    assert_eq!(mat("box/light").albedo, Vec3::new(0.78, 0.78, 0.78));
    assert!(!mat("box/floor").is_emitter());
    // The floor is 0.5528 x 0.5592 m give or take the published skew.
    let floor = s.mesh(&s.objects[0].mesh).unwrap();
    assert!((floor.area() - 0.3083).abs() < 1e-3, "{}", floor.area());
    assert!(s.objects.iter().all(|o| o.kind == ObjectKind::Real));
}

#[test]
fn bunny_loads_with_its_vertex_and_triangle_counts_and_normalises_height() {
    let s = load_root(&format!(
        "name = \"b\"\n[[object]]\nname = \"bunny\"\nmesh = \"{BUNNY}\"\nkind = \"virtual\"\n\
         normalize_height = 0.3\nanchor = \"bottom\"\ntranslation = [0.1, 0.02, -0.2]\n"
    ))
    .unwrap();
    assert_eq!(s.objects.len(), 1);
    assert_eq!(s.objects[0].name, "bunny");
    let mesh = s.mesh(&s.objects[0].mesh).unwrap();
    assert_eq!(mesh.positions.len(), 1839);
    assert_eq!(mesh.triangles.len(), 3674);
    let (lo, hi) = world_bounds(&s, "bunny");
    assert!((hi.y - lo.y - 0.3).abs() < 1e-5, "height {}", hi.y - lo.y);
    // Bottom anchor: the lowest point sits at the translation, centred in x, z.
    assert!((lo.y - 0.02).abs() < 1e-6);
    assert!((0.5 * (lo.x + hi.x) - 0.1).abs() < 1e-6);
    assert!((0.5 * (lo.z + hi.z) + 0.2).abs() < 1e-6);
    assert_eq!(s.objects[0].material.albedo, Vec3::splat(0.8));
}

#[test]
fn parts_and_exclude_parts_select_by_obj_object_name() {
    let s = load_root(&format!(
        "name = \"f\"\n\
         [[object]]\nname = \"room\"\nmesh = \"{CORNELL}\"\nkind = \"real\"\nexclude_parts = [\"short_block\", \"tall_block\", \"light\"]\n\
         [[object]]\nname = \"blocks\"\nmesh = \"{CORNELL}\"\nkind = \"virtual\"\nparts = [\"tall_block\", \"short_block\"]\n\
         albedo = [0.5, 0.5, 0.5]\n"
    ))
    .unwrap();
    assert_eq!(s.objects.len(), 7);
    assert_eq!(s.objects[5].name, "blocks/short_block");
    assert_eq!(s.objects[5].kind, ObjectKind::Virtual);
    assert_eq!(s.objects[5].material.albedo, Vec3::splat(0.5));
    // Both objects come from one file: the blocks share nothing with the
    // walls, and each mesh is stored once.
    assert_eq!(s.meshes.len(), 7);
}

#[test]
fn rotation_deg_is_xyz_euler_with_z_applied_first() {
    let rot = |deg: &str| {
        let s = load_root(&format!(
            "name = \"r\"\n[[object]]\nname = \"q\"\nmesh = \"builtin:quad\"\nkind = \"real\"\nrotation_deg = {deg}\n"
        ))
        .unwrap();
        s.objects[0].transform.rotation
    };
    // About y by 90 degrees: +x goes to -z.
    assert!((rot("[0, 90, 0]") * Vec3::X - Vec3::NEG_Z).length() < 1e-6);
    // Rx(90) Rz(90): +x -> +y (z first) -> +z (then x).
    assert!((rot("[90, 0, 90]") * Vec3::X - Vec3::Z).length() < 1e-6);
    let s = load_root(
        "name = \"r\"\n[[object]]\nname = \"q\"\nmesh = \"builtin:quad\"\nkind = \"real\"\nrotation_quat = [0, 0, 2, 2]\n",
    )
    .unwrap();
    // A non-unit quaternion is normalised: 90 degrees about z maps x to y.
    assert!((s.objects[0].transform.rotation * Vec3::X - Vec3::Y).length() < 1e-6);
}

#[test]
fn gltf_nodes_load_with_transforms_and_materials() {
    let s = load_fixture(
        "name = \"g\"\n[[object]]\nname = \"gl\"\nmesh = \"triangle.gltf\"\nkind = \"virtual\"\n",
    )
    .unwrap();
    let names: Vec<&str> = s.objects.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(names, ["gl/leaf", "gl/other"]);
    let leaf = s.mesh(&s.objects[0].mesh).unwrap();
    // Node "leaf" is scaled by 2 under "parent", translated by (1, 2, 3).
    assert_eq!(
        leaf.positions,
        [
            Vec3::new(1.0, 2.0, 3.0),
            Vec3::new(3.0, 2.0, 3.0),
            Vec3::new(1.0, 4.0, 3.0),
        ]
    );
    assert_eq!(leaf.triangles, [[0, 1, 2]]);
    let other = s.mesh(&s.objects[1].mesh).unwrap();
    assert_eq!(other.positions[1], Vec3::X);
    let m = &s.objects[0].material;
    assert_eq!(m.albedo, Vec3::new(0.2, 0.4, 0.6));
    assert_eq!(m.emission, Vec3::new(0.5, 0.25, 0.0));
    // The glTF mesh name selects every node that uses it.
    let s = load_fixture(
        "name = \"g\"\n[[object]]\nname = \"gl\"\nmesh = \"triangle.gltf\"\nkind = \"real\"\nparts = [\"tri\"]\n",
    )
    .unwrap();
    assert_eq!(s.objects.len(), 2);
    let s = load_fixture(
        "name = \"g\"\n[[object]]\nname = \"gl\"\nmesh = \"triangle.gltf\"\nkind = \"real\"\nparts = [\"other\"]\n",
    )
    .unwrap();
    assert_eq!(s.objects.len(), 1);
    assert_eq!(s.objects[0].name, "gl/other");
}

#[test]
fn binary_gltf_loads_like_its_text_twin() {
    let load = |file: &str| {
        load_fixture(&format!(
            "name = \"g\"\n[[object]]\nname = \"gl\"\nmesh = \"{file}\"\nkind = \"virtual\"\n"
        ))
        .unwrap()
    };
    let (text, binary) = (load("triangle.gltf"), load("triangle.glb"));
    assert_eq!(text.meshes, binary.meshes);
    assert_eq!(text.objects, binary.objects);
}

#[test]
fn calibration_file_gives_the_device_it_describes() {
    let s = load_fixture(
        "name = \"c\"\n[[projector]]\nname = \"projector-0\"\ncalibration = \"calibration-good.json\"\nnear = 0.1\nfar = 4.0\n",
    )
    .unwrap();
    let d = &s.projectors[0].device;
    assert_eq!((d.width, d.height), (1024, 768));
    assert_eq!(d.k.z_axis.x, 512.0);
    assert_eq!(d.dist_coeffs, [0.01, -0.002, 0.0, 0.0, 0.0]);
    assert_eq!((d.near, d.far), (0.1, 4.0));
    // The fixture was written for a device at (0.3, 0.7, 0.3) looking at
    // (0, 0.1, 0): its centre is there and the target projects to (cx, cy).
    assert!((d.center() - DVec3::new(0.3, 0.7, 0.3)).length() < 1e-12);
    let px = d.project(DVec3::new(0.0, 0.1, 0.0)).unwrap();
    assert!(
        (px - glam::DVec2::new(512.0, 384.0)).length() < 1e-9,
        "{px}"
    );
}

#[test]
fn inline_rotation_with_rounded_decimals_is_projected_to_a_rotation() {
    let s = load_root(
        "name = \"c\"\n[[camera]]\nname = \"cam\"\nwidth = 640\nheight = 480\n\
         camera_matrix = [[500, 0, 320], [0, 500, 240], [0, 0, 1]]\n\
         rotation = [[0.7071, 0, -0.7071], [0, 1, 0], [0.7071, 0, 0.7071]]\n\
         translation = [0, 0, 1]\n",
    )
    .unwrap();
    let r = s.cameras[0].device.rotation;
    let err = (r.transpose() * r - glam::DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .fold(0.0f64, |m, x| m.max(x.abs()));
    assert!(err < 1e-12, "{err}");
    assert!((r.determinant() - 1.0).abs() < 1e-12);
    assert!((r.x_axis.x - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-9);
}

#[test]
fn look_at_observer_faces_its_target() {
    let s = load_root(
        "name = \"o\"\n[[observer]]\nname = \"o\"\nposition = [1, 1, 1]\nlook_at = [1, 1, -3]\n\
         [[observer]]\nname = \"p\"\nposition = [0, 0, 2]\nlook_at = [0, 0, 0]\nipd = 0.07\n",
    )
    .unwrap();
    let o = &s.observers[0];
    assert!((o.head.orientation * Vec3::NEG_Z - Vec3::NEG_Z).length() < 1e-6);
    assert_eq!(o.ipd, 0.064);
    assert_eq!(s.observers[1].ipd, 0.07);
    let [l, r] = showcase_proto::Observer::eyes(&s.observers[1].head, 0.07);
    // Looking down -z from +z: the right eye is at +x.
    assert!((r - l - Vec3::new(0.07, 0.0, 0.0)).length() < 1e-6);
}

fn shipped(name: &str) -> Showcase {
    let path = root().join("deploy/scenes").join(name);
    let s = load_scene(&path).unwrap_or_else(|e| panic!("{e}"));
    s.validate().unwrap();
    s
}

#[test]
fn every_shipped_scene_loads_and_validates() {
    let dir = root().join("deploy/scenes");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let s = load_scene(&path).unwrap_or_else(|e| panic!("{e}"));
            s.validate().unwrap();
            n += 1;
        }
    }
    assert!(n >= 3, "only {n} scenes in {}", dir.display());
}

#[test]
fn cornell_scene_has_the_emitter_and_the_classic_camera() {
    let s = shipped("cornell.toml");
    assert_eq!(s.objects.len(), 8);
    let emitters: Vec<&str> = s
        .objects
        .iter()
        .filter(|o| o.material.is_emitter())
        .map(|o| o.name.as_str())
        .collect();
    assert_eq!(emitters, ["cornell/light"]);
    let cam = &s.cameras[0].device;
    assert!((cam.center() - DVec3::new(0.278, 0.273, -0.8)).length() < 1e-12);
    assert!(
        (cam.rotation.row(2) - DVec3::Z).length() < 1e-12,
        "looks along +z"
    );
    // Horizontal field of view: the principal point plus f tan(fov/2) is the edge.
    let f = cam.k.x_axis.x;
    let half = (0.5 * cam.width as f64 / f).atan().to_degrees();
    assert!((2.0 * half - 39.3077).abs() < 1e-9);
}

#[test]
fn figure3_scene_has_real_walls_virtual_blocks_and_a_virtual_light() {
    let s = shipped("figure3.toml");
    let real: Vec<&str> = s
        .objects
        .iter()
        .filter(|o| o.kind == ObjectKind::Real)
        .map(|o| o.name.as_str())
        .collect();
    assert_eq!(
        real,
        [
            "room/floor",
            "room/ceiling",
            "room/back",
            "room/right_green",
            "room/left_red"
        ]
    );
    let virt: Vec<&str> = s
        .objects
        .iter()
        .filter(|o| o.kind == ObjectKind::Virtual)
        .map(|o| o.name.as_str())
        .collect();
    assert_eq!(virt, ["blocks/short_block", "blocks/tall_block"]);
    assert!(
        s.objects.iter().all(|o| !o.material.is_emitter()),
        "the light is counted once"
    );
    let Light::Area {
        edge_u,
        edge_v,
        radiance,
        ..
    } = s.lights[0].light
    else {
        panic!("ceiling light is not an area light");
    };
    assert!(
        edge_u.cross(edge_v).normalize().dot(Vec3::NEG_Y) > 0.999,
        "emits downwards"
    );
    assert_eq!(radiance, Vec3::new(17.0, 12.0, 4.0));
    assert_eq!((s.projectors.len(), s.cameras.len()), (2, 1));
    // Each projector lights the back wall and both side walls through the
    // open front.
    for p in &s.projectors {
        for target in [
            DVec3::new(0.278, 0.274, 0.559),
            DVec3::new(0.0, 0.2, 0.3),
            DVec3::new(0.556, 0.2, 0.3),
        ] {
            let px = p.device.project(target).unwrap();
            assert!(
                (0.0..p.device.width as f64).contains(&px.x)
                    && (0.0..p.device.height as f64).contains(&px.y),
                "{} misses {target}: {px}",
                p.name
            );
        }
    }
}

#[test]
fn showcase_scene_fits_its_pyramid_beam_splitter() {
    let s = shipped("showcase.toml");
    assert_eq!(
        (
            s.faces.len(),
            s.projectors.len(),
            s.cameras.len(),
            s.observers.len()
        ),
        (2, 2, 1, 2)
    );
    // The four mirror planes of the pyramid (two carry faces): outward
    // normal cos 30 d + sin 30 y, through the floor edge at 0.6 d.
    let planes: Vec<showcase_proto::Plane> = [Vec3::X, Vec3::NEG_X, Vec3::Z, Vec3::NEG_Z]
        .map(|d| {
            showcase_proto::Plane::from_point_normal(
                0.6 * d,
                30f32.to_radians().cos() * d + 0.5 * Vec3::Y,
            )
        })
        .into();
    let inside = |p: Vec3| planes.iter().all(|pl| pl.normal.dot(p) - pl.offset < 1e-4);
    for o in &s.objects {
        let m = o.transform.matrix();
        for p in &s.mesh(&o.mesh).unwrap().positions {
            let w = m.transform_point3(*p);
            assert!(inside(w), "{} pokes out of the cabinet at {w}", o.name);
            assert!(w.y >= -1e-6, "{} is below the floor at {w}", o.name);
        }
    }
    for d in s
        .projectors
        .iter()
        .map(|p| &p.device)
        .chain(s.cameras.iter().map(|c| &c.device))
    {
        assert!(
            inside(d.center().as_vec3()),
            "device at {} is outside",
            d.center()
        );
    }
    for (face, observer) in s.faces.iter().zip(&s.observers) {
        let mirror = face.mirror;
        assert!(
            planes
                .iter()
                .any(|p| (p.normal - mirror.normal).length() < 1e-6
                    && (p.offset - mirror.offset).abs() < 1e-6)
        );
        let dist = |p: Vec3| mirror.normal.dot(p) - mirror.offset;
        assert!(
            dist(observer.head.position) > 0.0,
            "{} is behind its mirror",
            observer.name
        );
        let r = face.screen;
        let corners = [
            r.origin,
            r.origin + r.right,
            r.origin + r.down,
            r.origin + r.right + r.down,
        ];
        for c in corners {
            assert!(
                dist(c) > 0.0,
                "{} screen corner {c} is behind its mirror",
                face.name
            );
            // Its mirror image lies inside the cabinet, where virtual objects are.
            assert!(
                inside(mirror.reflect_point(c)),
                "{} image of {c} is outside",
                face.name
            );
        }
        assert!(
            r.normal().dot(-mirror.normal) > 0.5,
            "{} does not face its mirror",
            face.name
        );
    }
    let sphere = &s.objects[s.object_index("sphere").unwrap()];
    assert!(sphere.material.reflective && sphere.kind == ObjectKind::Virtual);
    let plate = &s.objects[s.object_index("plate").unwrap()];
    assert!(plate.material.texture.is_some() && plate.kind == ObjectKind::Real);
    let (lo, hi) = world_bounds(&s, "bunny");
    assert!((hi.y - lo.y - 0.15).abs() < 1e-5);
    let vb = s.object_index("virtual-bunny").unwrap();
    assert_eq!(
        s.objects[vb].mesh,
        s.objects[s.object_index("bunny").unwrap()].mesh,
        "one mesh, two bunnies"
    );
    assert!(matches!(s.lights[0].light, Light::Point { .. }));
}
