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
    assert!(s.objects.is_empty());
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
