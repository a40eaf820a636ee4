//! Unit tests of the scene-file loader: transforms, defaults and error paths
//! that need no data files.

use super::*;

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
