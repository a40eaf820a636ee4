//! Every WGSL file of the workspace parses and validates with naga (a
//! shared `.part.wgsl` piece as part of each shader that uses it); no GPU
//! needed.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, ensure};

/// Every `.wgsl` file under `dir`, skipping build output and hidden folders.
fn wgsl_files(dir: &Path, out: &mut Vec<PathBuf>) -> Result<()> {
    for entry in std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))? {
        let path = entry?.path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if path.is_dir() {
            if !name.starts_with('.') && name != "target" {
                wgsl_files(&path, out)?;
            }
        } else if path.extension().is_some_and(|e| e == "wgsl") {
            out.push(path);
        }
    }
    Ok(())
}

#[test]
fn every_wgsl_file_validates_with_naga() -> Result<()> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut files = Vec::new();
    wgsl_files(&root, &mut files)?;
    ensure!(
        files
            .iter()
            .any(|f| f.ends_with("render-node/src/gpu/flat_lambert/flat_lambert.wgsl")),
        "the walk under {} missed flat_lambert.wgsl: {files:?}",
        root.display()
    );
    // `NAME.part.wgsl` files are shared pieces: a shader that names one
    // is validated with it appended, as it is compiled (gpu::shadow_lookup).
    let (parts, shaders): (Vec<&PathBuf>, Vec<&PathBuf>) = files
        .iter()
        .partition(|f| f.to_string_lossy().ends_with(".part.wgsl"));
    let mut used = vec![false; parts.len()];
    let mut failures = Vec::new();
    for file in shaders {
        let mut source = std::fs::read_to_string(file)?;
        for (k, part) in parts.iter().enumerate() {
            let name = part.file_name().and_then(|n| n.to_str()).unwrap_or("");
            if source.contains(name) {
                used[k] = true;
                source.push('\n');
                source.push_str(&std::fs::read_to_string(part)?);
            }
        }
        let module = match naga::front::wgsl::parse_str(&source) {
            Ok(m) => m,
            Err(e) => {
                failures.push(format!("{}: {}", file.display(), e.emit_to_string(&source)));
                continue;
            }
        };
        let mut validator = naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::default(),
        );
        if let Err(e) = validator.validate(&module) {
            failures.push(format!("{}: {}", file.display(), e.emit_to_string(&source)));
        }
    }
    for (part, used) in parts.iter().zip(&used) {
        ensure!(*used, "no shader names {}", part.display());
    }
    ensure!(
        failures.is_empty(),
        "invalid WGSL:\n{}",
        failures.join("\n")
    );
    Ok(())
}
