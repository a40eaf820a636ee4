//! Unit tests of the scene-file loader: transforms, defaults and error paths
//! that need no data files.

use super::*;
use showcase_proto::{BeamSplitter, CrtPhotometry, CrtResponse};

#[track_caller]
fn load(text: &str) -> Result<Showcase, SceneError> {
    load_scene_str(text, Path::new("."), "unit.toml")
}

#[test]
fn empty_scene_gets_defaults() {
    let s = load("name = \"empty\"").unwrap();
    assert_eq!(s.name, "empty");
    assert_eq!(s.ambient, glam::Vec3::ZERO);
    assert_eq!(s.illumination, showcase_proto::IlluminationMode::Direct);
    assert!(s.objects.is_empty());
}

#[test]
fn illumination_is_direct_or_global() {
    let s = load("name = \"g\"\nillumination = \"global\"").unwrap();
    assert_eq!(s.illumination, showcase_proto::IlluminationMode::Global);
    let err = load("name = \"g\"\nillumination = \"radiosity\"")
        .unwrap_err()
        .to_string();
    assert!(err.contains("direct") && err.contains("global"), "{err}");
}

#[test]
fn a_scene_names_its_radiosity_patch_area_within_range() {
    assert_eq!(load("name = \"g\"").unwrap().patch_area, None);
    let s = load("name = \"g\"\npatch_area = 0.0025").unwrap();
    assert_eq!(s.patch_area, Some(0.0025));
    let err = load("name = \"g\"\npatch_area = -0.01")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("patch_area") && err.contains("outside 1e-6..=100 m^2"),
        "{err}"
    );
}

#[test]
fn deeply_nested_toml_is_an_error_not_a_crash() {
    for (open, close) in [("[", "]"), ("{a=", "}")] {
        let text = format!(
            "name = \"x\"\nambient = {}{}\n",
            open.repeat(100_000),
            close.repeat(100_000)
        );
        let err = load(&text).unwrap_err().to_string();
        assert!(err.starts_with("unit.toml:2:"), "{err}");
    }
}

#[test]
fn validation_paths_map_back_to_scene_file_labels() {
    let labels = Labels {
        objects: vec![
            "object[0] 'a'".into(),
            "object[1] 'room' part \"floor\"".into(),
        ],
        lights: vec!["light[0] 'l'".into()],
        ..Labels::default()
    };
    let field = |f: &str| {
        labels.field(&ValidationError {
            field: f.into(),
            problem: String::new(),
        })
    };
    assert_eq!(
        field("objects[1].material.albedo"),
        "object[1] 'room' part \"floor\".material.albedo"
    );
    assert_eq!(field("lights[0].samples"), "light[0] 'l'.samples");
    // Paths outside the lists, or past their end, stay as they are.
    assert_eq!(field("ambient"), "ambient");
    assert_eq!(field("objects[7].name"), "objects[7].name");
    assert_eq!(field("objects[x].name"), "objects[x].name");
}

#[test]
fn shared_mesh_files_are_parsed_once_and_meshes_stored_once() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/scenes");
    let text = "name = \"s\"\n\
        [[object]]\nname = \"a\"\nmesh = \"triangle.gltf\"\nkind = \"real\"\nparts = [\"other\"]\n\
        [[object]]\nname = \"b\"\nmesh = \"triangle.gltf\"\nkind = \"virtual\"\nparts = [\"other\"]\ntranslation = [1, 0, 0]\n";
    let s = load_scene_str(text, &dir, "unit.toml").unwrap();
    assert_eq!(s.objects.len(), 2);
    assert_eq!(s.meshes.len(), 1);
    assert_eq!(s.objects[0].mesh, s.objects[1].mesh);
    assert_eq!(s.objects[1].transform.translation, glam::Vec3::X);
}

/// `load_any` picks the reader by extension: a glTF file given whole is a
/// scene of real objects named after the file, its text and binary forms
/// alike; a mesh file's error names the file and line; anything else is
/// read as TOML.
#[test]
fn load_any_reads_mesh_files_whole_and_everything_else_as_toml() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/scenes");
    let text = load_any(&dir.join("triangle.gltf")).unwrap();
    assert_eq!(text.name, "triangle");
    assert!(!text.objects.is_empty());
    assert!(
        text.objects
            .iter()
            .all(|o| o.kind == showcase_proto::ObjectKind::Real)
    );
    assert_eq!(
        load_any(&dir.join("triangle.glb")).unwrap().objects,
        text.objects
    );
    let path = dir.join("broken.obj");
    let err = load_any(&path).unwrap_err().to_string();
    assert!(err.starts_with(&format!("{}:3: ", path.display())), "{err}");
    let err = load_any(&dir.join("calibration-good.json"))
        .unwrap_err()
        .to_string();
    assert!(err.contains("calibration-good.json:1:"), "{err}");
}

/// A face reads its CRT and splitter per channel, or the profile
/// `calibrate --photometric` wrote; stating both, a profile of another
/// face, and values out of range are errors naming the field.
#[test]
fn faces_read_their_photometry_or_a_measured_profile() {
    let dir = std::env::temp_dir().join(format!("showcase-profile-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let face = |extra: &str| {
        format!(
            "name = \"unit\"\n[[face]]\nname = \"face-0\"\nwidth = 64\nheight = 48\n\
             screen = {{ origin = [0.3, 0.6, 0.6], right = [-0.6, 0.0, 0.0], down = [0.0, -0.25, 0.43] }}\n\
             mirror = {{ point = [0.0, 0.0, 0.6], normal = [0.0, 0.5, 0.866] }}\n{extra}"
        )
    };
    let at = |text: &str| load_scene_str(text, &dir, "unit.toml");
    // Nominal by default; per channel when stated.
    let s = at(&face("")).unwrap();
    assert_eq!(s.faces[0].photometry, CrtPhotometry::nominal(2.2));
    let s = at(&face(
        "crt = { gamma = [2.4, 2.5, 2.3], peak = [1.0, 0.9, 1.1], black_level = [0.001, 0.001, 0.002] }\n\
         beam_splitter = { transmission = [0.6, 0.6, 0.55], reflection = [0.35, 0.35, 0.4] }\n",
    ))
    .unwrap();
    let p = s.faces[0].photometry;
    assert_eq!(p.crt.gamma, glam::Vec3::new(2.4, 2.5, 2.3));
    assert_eq!(p.splitter.reflection, glam::Vec3::new(0.35, 0.35, 0.4));
    // A measured profile.
    let profile = CrtPhotometry {
        crt: CrtResponse {
            gamma: glam::Vec3::new(2.45, 2.35, 2.6),
            peak: glam::Vec3::new(0.63, 0.52, 0.8),
            black_level: glam::Vec3::splat(0.0002),
        },
        splitter: BeamSplitter::IDEAL,
    };
    let write = |name: &str, face: &str, p: CrtPhotometry| {
        let file = crate::calibrate::photometric::ProfileFile {
            face: face.into(),
            photometry: p,
            held_out_error: Some(0.01),
            noise_floor: Some(20),
        };
        std::fs::write(dir.join(name), serde_json::to_string(&file).unwrap()).unwrap();
    };
    write("p.json", "face-0", profile);
    let s = at(&face("photometric_profile = \"p.json\"\n")).unwrap();
    assert_eq!(s.faces[0].photometry, profile);
    let err = |extra: &str| at(&face(extra)).unwrap_err().to_string();
    let e = err("photometric_profile = \"p.json\"\ngamma = 2.2\n");
    assert!(
        e.contains("photometric_profile") && e.contains("not both"),
        "{e}"
    );
    write("other.json", "face-1", profile);
    let e = err("photometric_profile = \"other.json\"\n");
    assert!(e.contains("face-1") && e.contains("own profile"), "{e}");
    let mut bad = profile;
    bad.crt.peak.y = -1.0;
    write("bad.json", "face-0", bad);
    let e = err("photometric_profile = \"bad.json\"\n");
    assert!(e.contains("crt.peak"), "{e}");
    let e = err("photometric_profile = \"missing.json\"\n");
    assert!(
        e.contains("missing.json") && e.contains("cannot read"),
        "{e}"
    );
    let e = err("crt = { gamma = [2.4, 2.5, 2.3], peak = [1.0, 0.9, 1.1] }\ngamma = 2.2\n");
    assert!(e.contains("not both"), "{e}");
    let e =
        err("beam_splitter = { transmission = [0.6, 0.6, 0.55], reflection = [0.35, 0.0, 0.4] }\n");
    assert!(e.contains("reflection"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A key missing at the top level is said to be missing there, not in
/// whatever table the file happens to begin with.
#[test]
fn a_missing_top_level_key_names_the_top_level() {
    let e = load(
        "[[face]]\nname = \"face-0\"\nwidth = 64\nheight = 48\n\
         screen = { origin = [0.3, 0.6, 0.6], right = [-0.6, 0.0, 0.0], down = [0.0, -0.25, 0.43] }\n\
         mirror = { point = [0.0, 0.0, 0.6], normal = [0.0, 0.5, 0.866] }\n",
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("missing field `name`"), "{e}");
    assert!(
        e.contains("top level") && !e.contains("in `[[face]]`"),
        "{e}"
    );
}

/// A projector reads its own light per channel, or the profile
/// `calibrate --photometric` wrote; none is its model alone; stating both,
/// a profile of another projector, a falling curve and a camera with the
/// key are errors naming the field.
#[test]
fn projectors_read_their_photometry_or_a_measured_profile() {
    let dir =
        std::env::temp_dir().join(format!("showcase-projector-profile-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let projector = |extra: &str| {
        format!(
            "name = \"unit\"\n[[projector]]\nname = \"projector-0\"\nwidth = 64\nheight = 48\n\
             look_at = {{ eye = [0.0, 1.0, 0.0], target = [0.0, 0.0, 0.0], up = [0.0, 0.0, 1.0], \
             fov_deg = 60.0 }}\n{extra}"
        )
    };
    let at = |text: &str| load_scene_str(text, &dir, "unit.toml");
    let s = at(&projector("")).unwrap();
    assert_eq!(s.projectors[0].response.photometry, None);
    let s = at(&projector(
        "photometry = { gamma = [2.3, 2.1, 2.5], peak = [3.9, 4.0, 3.8], black_level = [0.005, 0.004, 0.006] }\n",
    ))
    .unwrap();
    let p = s.projectors[0].response.photometry.unwrap();
    assert_eq!(p.gamma, glam::Vec3::new(2.3, 2.1, 2.5));
    assert_eq!(p.black_level, glam::Vec3::new(0.005, 0.004, 0.006));
    let curve = CrtResponse {
        gamma: glam::Vec3::new(2.34, 2.11, 2.49),
        peak: glam::Vec3::new(3.99, 3.98, 4.0),
        black_level: glam::Vec3::splat(0.005),
    };
    let write = |name: &str, projector: &str, c: CrtResponse| {
        let file = crate::calibrate::photometric::ProjectorProfileFile {
            projector: projector.into(),
            photometry: c,
            held_out_error: Some(0.004),
        };
        std::fs::write(dir.join(name), serde_json::to_string(&file).unwrap()).unwrap();
    };
    write("p.json", "projector-0", curve);
    let s = at(&projector("photometric_profile = \"p.json\"\n")).unwrap();
    assert_eq!(s.projectors[0].response.photometry, Some(curve));
    let err = |extra: &str| at(&projector(extra)).unwrap_err().to_string();
    let e = err(
        "photometric_profile = \"p.json\"\nphotometry = { gamma = [2.2, 2.2, 2.2], peak = [1.0, 1.0, 1.0] }\n",
    );
    assert!(
        e.contains("photometric_profile") && e.contains("not both"),
        "{e}"
    );
    write("other.json", "projector-1", curve);
    let e = err("photometric_profile = \"other.json\"\n");
    assert!(
        e.contains("projector-1") && e.contains("own profile"),
        "{e}"
    );
    let mut bad = curve;
    bad.gamma.z = 0.0;
    write("bad.json", "projector-0", bad);
    let e = err("photometric_profile = \"bad.json\"\n");
    assert!(e.contains("photometry.gamma"), "{e}");
    let e = err("photometry = { gamma = [2.2, 2.2, 2.2], peak = [1.0, -1.0, 1.0] }\n");
    assert!(e.contains("photometry.peak"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}
