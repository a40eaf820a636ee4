//! Property tests: arbitrary and mutated scene, OBJ and glTF text never
//! panics; a load either validates or fails naming the scene file.

use super::{fixtures, load_fixture};
use proptest::prelude::*;
use showcase_master::scene_file::load_scene_str;
use showcase_proto::Validate;

/// A valid scene with a bit of everything, for mutation.
const SEED_SCENE: &str = r#"name = "seed"
ambient = [0.01, 0.01, 0.01]
[[object]]
name = "plate"
mesh = "builtin:plate"
kind = "real"
size = [0.2, 0.1]
subdivisions = 2
translation = [0, 0.01, 0]
rotation_deg = [0, 45, 0]
texture = { type = "checker", cells = 4, a = [0.9, 0.9, 0.9], b = [0.1, 0.1, 0.1] }
[[object]]
name = "ball"
mesh = "builtin:sphere"
kind = "virtual"
radius = 0.05
segments = 6
[[object]]
name = "gl"
mesh = "triangle.gltf"
kind = "virtual"
parts = ["leaf"]
[[light]]
name = "lamp"
type = "spot"
position = [0, 1, 0]
direction = [0, -1, 0]
intensity = [1, 1, 1]
inner_deg = 10
outer_deg = 30
[[projector]]
name = "p"
width = 64
height = 48
camera_matrix = [[50, 0, 32], [0, 50, 24], [0, 0, 1]]
rotation = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
translation = [0, 0, 1]
[[camera]]
name = "c"
calibration = "calibration-good.json"
[[face]]
name = "f"
width = 64
height = 48
screen = { origin = [0, 1, 0], right = [1, 0, 0], down = [0, -1, 0] }
mirror = { point = [0, 0, 0.5], normal = [0, 0.5, 0.866] }
[[observer]]
name = "o"
position = [0, 0.4, 1.4]
look_at = [0, 0, 0]
"#;

#[test]
fn seed_scene_for_the_property_tests_is_valid() {
    let s = load_fixture(SEED_SCENE).unwrap();
    assert_eq!(s.objects.len(), 3);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn arbitrary_text_never_panics(text in "\\PC{0,200}") {
        let _ = load_fixture(&text);
    }

    #[test]
    fn mutated_scenes_never_panic_and_errors_name_the_file(
        edits in proptest::collection::vec((any::<prop::sample::Index>(), 0u8..6, any::<char>()), 1..6),
    ) {
        let mut text: Vec<char> = SEED_SCENE.chars().collect();
        let tokens = ["nan", "-inf", "1e300", "-1", "0", "[]", "\"\"", "\n[[object]]\n", "\"builtin:quad\"", "99999999999"];
        for (at, op, c) in edits {
            if text.is_empty() {
                text.push(c);
                continue;
            }
            let i = at.index(text.len());
            match op {
                0 => { text.remove(i); }
                1 => text.insert(i, c),
                2 => text[i] = c,
                _ => {
                    // Replace the number or word at i by a hostile token.
                    let start = (0..=i).rev().find(|&k| k == 0 || !text[k - 1].is_alphanumeric() && text[k - 1] != '.').unwrap_or(0);
                    let end = (i..text.len()).find(|&k| !text[k].is_alphanumeric() && text[k] != '.').unwrap_or(text.len());
                    let token = tokens[(c as usize) % tokens.len()];
                    text.splice(start..end.max(start), token.chars());
                }
            }
        }
        let text: String = text.into_iter().collect();
        match load_fixture(&text) {
            Ok(s) => prop_assert!(s.validate().is_ok()),
            Err(e) => prop_assert!(e.to_string().contains("case.toml"), "{e}"),
        }
    }

    #[test]
    fn mutated_mesh_files_never_panic(
        gltf in any::<bool>(),
        edits in proptest::collection::vec((any::<prop::sample::Index>(), 0u8..3, any::<u8>()), 1..8),
    ) {
        let (source, ext) = if gltf { ("triangle.gltf", "gltf") } else { ("broken.obj", "obj") };
        let mut bytes = std::fs::read(fixtures().join(source)).unwrap();
        if !gltf {
            // A valid OBJ to start from: the broken fixture minus its bad line.
            bytes = b"o a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1/1/1 2/1/1 3/1/1\no b\nf -1 -2 -3\n".to_vec();
        }
        for (at, op, b) in edits {
            if bytes.is_empty() {
                bytes.push(b);
                continue;
            }
            let i = at.index(bytes.len());
            match op {
                0 => { bytes.remove(i); }
                1 => bytes.insert(i, b),
                _ => bytes[i] = b,
            }
        }
        let dir = std::env::temp_dir().join(format!("showcase-scene-files-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(format!("mutated-{:?}.{ext}", std::thread::current().id()).replace(['(', ')'], ""));
        std::fs::write(&path, &bytes).unwrap();
        let text = format!("name = \"m\"\n[[object]]\nname = \"m\"\nkind = \"real\"\nmesh = {:?}\n", path.display().to_string());
        let result = load_scene_str(&text, &dir, "case.toml");
        std::fs::remove_file(&path).ok();
        match result {
            Ok(s) => prop_assert!(s.validate().is_ok()),
            Err(e) => prop_assert!(e.to_string().contains("case.toml"), "{e}"),
        }
    }
}
