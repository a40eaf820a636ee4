//! The built-in scenes and the data they use, compiled into the binary so
//! that an installed `showcase-master` runs `demo`, `replay` and `bench`
//! with no source tree beside it.
//!
//! A built-in scene is named `builtin:NAME` (`builtin:showcase`, the demo
//! cabinet; `builtin:figure3`; `builtin:cornell`). Its files live under
//! the virtual root `builtin:/`, laid out as in the repository
//! (`builtin:/repo/deploy/scenes/NAME.toml`) and the shared data beside it
//! (`builtin:/shared/data/...`), so the scene files' own relative mesh
//! paths (`../../../shared/data/cornell-box.obj`) resolve unchanged.
//! Paths that do not start with `builtin:` are files on disk, read as
//! before.

use std::io;
use std::path::{Path, PathBuf};

/// The prefix of a built-in scene name (`builtin:showcase`).
pub(crate) const PREFIX: &str = "builtin:";

/// The virtual root of the built-in files.
const ROOT: &str = "builtin:/";

/// The built-in scenes, by name.
pub const SCENES: [&str; 3] = ["showcase", "figure3", "cornell"];

/// Every built-in file, by its path under [`ROOT`].
static FILES: [(&str, &[u8]); 6] = [
    (
        "repo/deploy/scenes/showcase.toml",
        include_bytes!("../../../deploy/scenes/showcase.toml"),
    ),
    (
        "repo/deploy/scenes/figure3.toml",
        include_bytes!("../../../deploy/scenes/figure3.toml"),
    ),
    (
        "repo/deploy/scenes/cornell.toml",
        include_bytes!("../../../deploy/scenes/cornell.toml"),
    ),
    (
        "shared/data/cornell-box.obj",
        include_bytes!("../../../../shared/data/cornell-box.obj"),
    ),
    (
        "shared/data/cornell-box.mtl",
        include_bytes!("../../../../shared/data/cornell-box.mtl"),
    ),
    (
        "shared/data/bunny.obj",
        include_bytes!("../../../../shared/data/bunny.obj"),
    ),
];

/// The path of built-in scene `builtin:NAME` (`scene`), or `None` when
/// `scene` is no built-in name; an unknown name is an error listing the
/// known ones.
pub(crate) fn scene_file(scene: &Path) -> Option<Result<PathBuf, String>> {
    let name = scene.to_str()?.strip_prefix(PREFIX)?;
    if name.starts_with('/') {
        return None;
    }
    Some(if SCENES.contains(&name) {
        Ok(PathBuf::from(format!(
            "{ROOT}repo/deploy/scenes/{name}.toml"
        )))
    } else {
        Err(format!(
            "unknown built-in scene {name:?} (expected {})",
            SCENES.map(|s| format!("{PREFIX}{s}")).join(", ")
        ))
    })
}

/// A file of the shared data set as built into the binary
/// (`cornell-box.obj`, `bunny.obj`), for the benches' defaults.
pub fn shared_data(name: &str) -> PathBuf {
    PathBuf::from(format!("{ROOT}shared/data/{name}"))
}

/// Whether `path` names a built-in scene or file (`builtin:...`), which
/// is never joined to a folder or looked up on disk.
pub fn is_builtin(path: &Path) -> bool {
    path.to_str().is_some_and(|p| p.starts_with(PREFIX))
}

/// The contents of built-in file `path`, or `None` when `path` is not
/// under the virtual root (a file on disk); a built-in path that names no
/// file is `NotFound`.
pub(crate) fn read(path: &Path) -> Option<io::Result<&'static [u8]>> {
    let rest = path.to_str()?.strip_prefix(ROOT)?;
    let mut parts: Vec<&str> = Vec::new();
    for part in rest.split('/') {
        match part {
            "" | "." => {}
            ".." => {
                if parts.pop().is_none() {
                    return Some(Err(not_found(path)));
                }
            }
            p => parts.push(p),
        }
    }
    let key = parts.join("/");
    Some(
        FILES
            .iter()
            .find(|(name, _)| *name == key)
            .map(|(_, bytes)| *bytes)
            .ok_or_else(|| not_found(path)),
    )
}

fn not_found(path: &Path) -> io::Error {
    io::Error::new(
        io::ErrorKind::NotFound,
        format!(
            "{} is not built into this binary (built-in scenes: {})",
            path.display(),
            SCENES.map(|s| format!("{PREFIX}{s}")).join(", ")
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn built_in_paths_resolve_like_the_repository() {
        let scene = scene_file(Path::new("builtin:showcase")).unwrap().unwrap();
        let toml = read(&scene).unwrap().unwrap();
        assert!(
            std::str::from_utf8(toml)
                .unwrap()
                .contains("name = \"showcase\"")
        );
        // The scene's own relative mesh path, joined to its folder.
        let mesh = scene
            .parent()
            .unwrap()
            .join("../../../shared/data/bunny.obj");
        assert_eq!(
            read(&mesh).unwrap().unwrap(),
            include_bytes!("../../../../shared/data/bunny.obj")
        );
        assert_eq!(
            read(&shared_data("cornell-box.mtl")).unwrap().unwrap(),
            include_bytes!("../../../../shared/data/cornell-box.mtl")
        );
        // Not built in: an error naming the path; not under the root: disk.
        let e = read(Path::new("builtin:/shared/data/teapot.obj"))
            .unwrap()
            .unwrap_err();
        assert!(e.to_string().contains("teapot.obj"), "{e}");
        assert!(
            read(Path::new("builtin:/../../etc/passwd"))
                .unwrap()
                .is_err()
        );
        assert!(read(Path::new("deploy/scenes/showcase.toml")).is_none());
        let e = scene_file(Path::new("builtin:nope")).unwrap().unwrap_err();
        assert!(e.contains("builtin:showcase"), "{e}");
        assert!(scene_file(Path::new("showcase.toml")).is_none());
    }
}
