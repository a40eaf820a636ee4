//! Scene-file errors: every kind of bad input is an `Err` whose message
//! names the file and the field or line (data-driven `check`).

use super::{fixtures, load_fixture};
use showcase_master::scene_file::load_scene;

/// Load `text` from the fixtures folder and check the error message holds
/// every expected piece.
#[track_caller]
fn check(text: &str, expected: &[&str]) {
    let err = match load_fixture(text) {
        Ok(_) => panic!("loaded without error:\n{text}"),
        Err(e) => e.to_string(),
    };
    assert!(err.contains("case.toml"), "no file name in {err:?}");
    for e in expected {
        assert!(err.contains(e), "{e:?} not in {err:?}");
    }
}

const OBJ: &str = "[[object]]\nname = \"m\"\nkind = \"real\"\n";
const PROJ: &str = "[[projector]]\nname = \"p\"\nwidth = 640\nheight = 480\n";
const K: &str = "camera_matrix = [[500, 0, 320], [0, 500, 240], [0, 0, 1]]\n";
const R: &str = "rotation = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]\ntranslation = [0, 0, 1]\n";
const LOOK: &str = "look_at = { eye = [0, 0, 0], target = [0, 0, 1], fov_deg = 40 }\n";

#[test]
fn toml_errors_name_the_line_and_column() {
    check("name = \"x\"\n[[object]\n", &["case.toml:2:"]);
    check(
        "name = \"x\"\ncolour = 1\n",
        &["case.toml:2:1:", "unknown field `colour`"],
    );
    check("name = 3\n", &["case.toml:1:8:", "invalid type"]);
    check("", &["case.toml", "missing field `name`"]);
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"builtin:quad\"\ncolor = [1, 0, 0]\n"),
        &["case.toml:6:1:", "unknown field `color`"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"builtin:quad\"\nkind2 = 1\n"),
        &["case.toml:6:", "kind2"],
    );
    check(
        "name = \"x\"\n[[object]]\nname = \"m\"\nmesh = \"builtin:quad\"\nkind = \"imaginary\"\n",
        &["case.toml:5:", "imaginary"],
    );
    check(
        &format!("name = \"x\"\n{PROJ}{K}{R}bits = -1\n"),
        &["case.toml:9:", "bits = -1"],
    );
    check(
        &format!("name = \"x\"\n{PROJ}{LOOK}width2 = 3\n"),
        &["case.toml:7:", "width2"],
    );
}

#[test]
fn non_finite_numbers_are_rejected_naming_the_field() {
    check(
        "name = \"x\"\nambient = [0, nan, 0]\n",
        &["case.toml:2:", "not finite", "ambient"],
    );
    check(
        "name = \"x\"\n[[light]]\nname = \"l\"\ntype = \"point\"\nposition = [0, inf, 0]\nintensity = [1, 1, 1]\n",
        &["case.toml:5:", "inf is not finite", "position"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"builtin:quad\"\nscale = -inf\n"),
        &["case.toml:6:9:", "-inf is not finite", "scale"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"builtin:quad\"\nscale = [1, nan, 1]\n"),
        &["case.toml:6:", "NaN is not finite", "scale"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"builtin:quad\"\nscale = [1, 1]\n"),
        &["case.toml:6:", "invalid length 2", "scale"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"builtin:quad\"\nscale = \"big\"\n"),
        &["case.toml:6:", "a number or an array of 3 numbers"],
    );
    check(
        &format!("name = \"x\"\n{PROJ}{LOOK}near = nan\n"),
        &["case.toml:7:", "near"],
    );
    check(
        "name = \"x\"\nambient = [0, 1e300, 0]\n",
        &["case.toml:2:", "1e300 is outside", "ambient"],
    );
}

#[test]
fn degenerate_device_matrices_are_rejected_naming_the_device() {
    let singular = "camera_matrix = [[0, 0, 320], [0, 500, 240], [0, 0, 1]]\n";
    check(
        &format!("name = \"x\"\n{PROJ}{singular}{R}"),
        &["projector[0] 'p'.camera_matrix", "singular"],
    );
    let lower = "camera_matrix = [[500, 0, 320], [3, 500, 240], [0, 0, 1]]\n";
    check(
        &format!("name = \"x\"\n{PROJ}{lower}{R}"),
        &["projector[0] 'p'.camera_matrix", "upper triangular"],
    );
    let negative = "camera_matrix = [[-500, 0, 320], [0, -500, 240], [0, 0, 1]]\n";
    check(
        &format!("name = \"x\"\n{PROJ}{negative}{R}"),
        &["camera_matrix", "must be positive"],
    );
    let skewed = "rotation = [[1, 0.1, 0], [0, 1, 0], [0, 0, 1]]\ntranslation = [0, 0, 1]\n";
    let second = "[[projector]]\nname = \"projector-1\"\nwidth = 640\nheight = 480\n";
    check(
        &format!("name = \"x\"\n{PROJ}{K}{R}{second}{K}{skewed}"),
        &["case.toml: projector[1] 'projector-1'.rotation: rotation is not orthonormal"],
    );
    let mirrored = "rotation = [[-1, 0, 0], [0, 1, 0], [0, 0, 1]]\ntranslation = [0, 0, 1]\n";
    check(
        &format!("name = \"x\"\n{PROJ}{K}{mirrored}"),
        &["projector[0] 'p'.rotation", "reflection"],
    );
    check(
        &format!("name = \"x\"\n{PROJ}{K}"),
        &["projector[0] 'p'.rotation", "needs `rotation`"],
    );
    check(
        &format!("name = \"x\"\n{PROJ}{K}{R}{LOOK}"),
        &["projector[0] 'p'", "exactly one of"],
    );
    check(
        &format!("name = \"x\"\n{PROJ}"),
        &["projector[0] 'p'", "exactly one of"],
    );
    let same = "look_at = { eye = [1, 1, 1], target = [1, 1, 1], fov_deg = 40 }\n";
    check(
        &format!("name = \"x\"\n{PROJ}{same}"),
        &["projector[0] 'p'.look_at", "eye and target"],
    );
    let up = "look_at = { eye = [0, 0, 0], target = [0, 1, 0], fov_deg = 40 }\n";
    check(
        &format!("name = \"x\"\n{PROJ}{up}"),
        &["projector[0] 'p'.look_at.up", "parallel"],
    );
    let fov = "look_at = { eye = [0, 0, 0], target = [0, 0, 1], fov_deg = 180 }\n";
    check(
        &format!("name = \"x\"\n{PROJ}{fov}"),
        &["look_at.fov_deg", "180"],
    );
    check(
        &format!("name = \"x\"\n{PROJ}{LOOK}near = 2\nfar = 1\n"),
        &["projector[0] 'p'.far", "near < far"],
    );
    let no_size = "[[camera]]\nname = \"c\"\n";
    check(
        &format!("name = \"x\"\n{no_size}{LOOK}"),
        &["camera[0] 'c'.width", "needs `width`"],
    );
    check(
        &format!("name = \"x\"\n[[camera]]\nname = \"c\"\nwidth = 0\nheight = 480\n{LOOK}"),
        &["camera[0] 'c'.device.width", "0x480"],
    );
    check(
        &format!("name = \"x\"\n{PROJ}{LOOK}gain = 2\n"),
        &["projector[0] 'p'.gain", "does not apply"],
    );
    check(
        &format!("name = \"x\"\n[[camera]]\nname = \"c\"\nwidth = 4\nheight = 4\n{LOOK}eta = 2\n"),
        &["camera[0] 'c'.eta", "does not apply"],
    );
    check(
        &format!("name = \"x\"\n{PROJ}{LOOK}gamma = 0\n"),
        &["projector[0] 'p'.response.gamma"],
    );
}

#[test]
fn calibration_file_errors_name_both_files() {
    let cal = |f: &str| format!("name = \"x\"\n[[camera]]\nname = \"c\"\ncalibration = \"{f}\"\n");
    check(
        &cal("nope.json"),
        &["camera[0] 'c'.calibration", "nope.json", "cannot read"],
    );
    check(
        &cal("calibration-bad-rotation.json"),
        &[
            "calibration-bad-rotation.json",
            "rotation is not orthonormal",
        ],
    );
    check(
        &cal("calibration-bad-projection.json"),
        &["calibration-bad-projection.json", "projection", "disagrees"],
    );
    check(
        &cal("calibration-syntax.json"),
        &["calibration-syntax.json:3:"],
    );
    check(
        &format!("{}width = 800\n", cal("calibration-good.json")),
        &["camera[0] 'c'.width", "800 differs from 1024"],
    );
}

#[test]
fn mesh_file_errors_name_both_files_and_the_line() {
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"missing.obj\"\n"),
        &["object[0] 'm'.mesh", "missing.obj", "cannot read"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"broken.obj\"\n"),
        &[
            "object[0] 'm'.mesh",
            "broken.obj:3:",
            "position parse error",
        ],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"no-mtl.obj\"\n"),
        &["no-mtl.obj", "missing.mtl"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"unknown-material.obj\"\n"),
        &["unknown-material.obj:5:", "usemtl blue", "no such material"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"nan-vertex.obj\"\n"),
        &["nan-vertex.obj", "positions[1]", "not finite"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"cube.stl\"\n"),
        &["cube.stl", "unknown mesh format"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"overrun.gltf\"\n"),
        &["overrun.gltf", "runs past the end"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"calibration-syntax.json\"\n"),
        &["unknown mesh format"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"builtin:cone\"\n"),
        &["object[0] 'm'.mesh", "builtin:cone"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"builtin:sphere\"\nsize = [1, 1]\n"),
        &["object[0] 'm'.size", "does not apply"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"builtin:plate\"\nsubdivisions = 0\n"),
        &["object[0] 'm'.subdivisions"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"builtin:sphere\"\nradius = 0\n"),
        &["object[0] 'm'.radius", "positive"],
    );
}

#[test]
fn object_errors_name_the_object_and_field() {
    let cornell = "../../../../shared/data/cornell-box.obj";
    let bunny = "../../../../shared/data/bunny.obj";
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"{cornell}\"\nparts = [\"floor\", \"sofa\"]\n"),
        &[
            "object[0] 'm'.parts",
            "no part named \"sofa\"",
            "available: \"floor\", \"ceiling\"",
            "\"light\"",
        ],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"{cornell}\"\nexclude_parts = [\"lamp\"]\n"),
        &["object[0] 'm'.exclude_parts", "lamp"],
    );
    check(
        &format!(
            "name = \"x\"\n{OBJ}mesh = \"triangle.gltf\"\nparts = [\"tri\"]\nexclude_parts = [\"tri\"]\n"
        ),
        &["object[0] 'm'.parts", "no parts"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"builtin:quad\"\n{OBJ}mesh = \"builtin:quad\"\n"),
        &[
            "object[1] 'm'.name",
            "duplicate name \"m\", also used by object[0]",
        ],
    );
    check(
        &format!(
            "name = \"x\"\n[[object]]\nname = \"c/floor\"\nkind = \"real\"\nmesh = \"builtin:quad\"\n[[object]]\nname = \"c\"\nkind = \"real\"\nmesh = \"{cornell}\"\n"
        ),
        &[
            "object[1] 'c' part \"floor\".name",
            "duplicate name \"c/floor\"",
        ],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"builtin:quad\"\nalbedo = [1.5, 0, 0]\n"),
        &["object[0] 'm'.material.albedo", "exceeds 1"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"builtin:quad\"\nemission = [-1, 0, 0]\n"),
        &["object[0] 'm'.material.emission", "negative"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"builtin:quad\"\nscale = [1, 0, 1]\n"),
        &["object[0] 'm'.scale", "positive"],
    );
    check(
        &format!(
            "name = \"x\"\n{OBJ}mesh = \"builtin:quad\"\nrotation_deg = [0, 0, 0]\nrotation_quat = [0, 0, 0, 1]\n"
        ),
        &["object[0] 'm'.rotation_quat", "not both"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"builtin:quad\"\nrotation_quat = [0, 0, 0, 0]\n"),
        &["rotation_quat", "zero"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"builtin:quad\"\nnormalize_height = 0.3\n"),
        &["object[0] 'm'.normalize_height", "flat"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"{bunny}\"\nnormalize_height = 0.3\nscale = 2\n"),
        &["normalize_height", "not both"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"{bunny}\"\nnormalize_height = -1\n"),
        &["normalize_height", "positive"],
    );
    check(
        &format!(
            "name = \"x\"\n{OBJ}mesh = \"{bunny}\"\ntexture = {{ type = \"checker\", cells = 4, a = [1, 1, 1], b = [0, 0, 0] }}\n"
        ),
        &["object[0] 'm'.texture", "texture coordinates"],
    );
    check(
        &format!(
            "name = \"x\"\n{OBJ}mesh = \"builtin:plate\"\ntexture = {{ type = \"wood\", light = [2, 1, 1], dark = [0, 0, 0], rings = 3 }}\n"
        ),
        &["object[0] 'm'.material.texture.a", "exceeds 1"],
    );
    check(
        &format!("name = \"x\"\n{OBJ}mesh = \"builtin:quad\"\nreflectance_map = \"\"\n"),
        &["object[0] 'm'.material.reflectance_map", "empty"],
    );
    check(
        "name = \"x\"\n[[object]]\nname = \"\"\nkind = \"real\"\nmesh = \"builtin:quad\"\n",
        &["object[0] ''.name", "empty"],
    );
}

#[test]
fn light_face_and_observer_errors_name_the_field() {
    let l = "[[light]]\nname = \"l\"\n";
    check(
        &format!("name = \"x\"\n{l}type = \"point\"\nposition = [0, 0, 0]\n"),
        &["light[0] 'l'.intensity", "needs `intensity`"],
    );
    check(
        &format!(
            "name = \"x\"\n{l}type = \"point\"\nposition = [0, 0, 0]\nintensity = [1, 1, 1]\nradiance = [1, 1, 1]\n"
        ),
        &["light[0] 'l'.radiance", "does not apply to a point light"],
    );
    check(
        &format!(
            "name = \"x\"\n{l}type = \"spot\"\nposition = [0, 0, 0]\nintensity = [1, 1, 1]\ndirection = [0, 0, 0]\ninner_deg = 10\nouter_deg = 20\n"
        ),
        &["light[0] 'l'.direction", "zero"],
    );
    check(
        &format!(
            "name = \"x\"\n{l}type = \"spot\"\nposition = [0, 0, 0]\nintensity = [1, 1, 1]\ndirection = [0, -1, 0]\ninner_deg = 30\nouter_deg = 20\n"
        ),
        &["light[0] 'l'.outer_deg"],
    );
    check(
        &format!(
            "name = \"x\"\n{l}type = \"area\"\ncorner = [0, 0, 0]\nedge_u = [1, 0, 0]\nedge_v = [2, 0, 0]\nradiance = [1, 1, 1]\n"
        ),
        &["light[0] 'l'.edge_v", "no area"],
    );
    check(
        &format!(
            "name = \"x\"\n{l}type = \"area\"\ncorner = [0, 0, 0]\nedge_u = [1, 0, 0]\nedge_v = [0, 0, 1]\nradiance = [1, 1, 1]\nsamples = 0\n"
        ),
        &["light[0] 'l'.samples"],
    );
    let f = "[[face]]\nname = \"f\"\nwidth = 640\nheight = 480\nscreen = { origin = [0, 1, 0], right = [1, 0, 0], down = [0, -1, 0] }\n";
    check(
        &format!("name = \"x\"\n{f}mirror = {{ point = [0, 0, 0], normal = [0, 0, 0] }}\n"),
        &["face[0] 'f'.mirror.normal", "zero"],
    );
    let flat = "[[face]]\nname = \"f\"\nwidth = 640\nheight = 480\nscreen = { origin = [0, 1, 0], right = [1, 0, 0], down = [2, 0, 0] }\n";
    check(
        &format!("name = \"x\"\n{flat}mirror = {{ point = [0, 0, 0], normal = [0, 0, 1] }}\n"),
        &["face[0] 'f'.screen", "zero area"],
    );
    let o = "[[observer]]\nname = \"o\"\nposition = [0, 0, 1]\n";
    check(
        &format!("name = \"x\"\n{o}ipd = 0.5\n"),
        &["observer[0] 'o'.ipd", "outside"],
    );
    check(
        &format!("name = \"x\"\n{o}look_at = [0, 0, 1]\n"),
        &["observer[0] 'o'.look_at", "at its target"],
    );
    check(
        &format!("name = \"x\"\n{o}look_at = [0, 5, 1]\n"),
        &["observer[0] 'o'.up", "parallel"],
    );
    check(
        &format!("name = \"x\"\n{o}look_at = [0, 0, 0]\norientation_quat = [0, 0, 0, 1]\n"),
        &["observer[0] 'o'", "not both"],
    );
    check(
        &format!("name = \"x\"\n{o}{o}"),
        &["observer[1] 'o'.name", "duplicate"],
    );
}

#[test]
fn missing_scene_file_names_the_file() {
    let path = fixtures().join("no-such-scene.toml");
    let err = load_scene(&path).unwrap_err().to_string();
    assert!(
        err.contains("no-such-scene.toml") && err.contains("cannot read"),
        "{err}"
    );
}
