//! `showcase-master check --config CLUSTER.toml`: everything `run` and the
//! nodes will load, checked before a show, with every problem reported at
//! once, each with its file and what to do. It uses the loaders `run` and
//! `showcase-node` use (config, scene, certificates, tracking, address
//! resolution) but goes on after a problem instead of stopping.

use crate::scene_file::{self, SceneNames};
use crate::tracking::{recording, resolve_target};
use showcase_proto::config::{ClusterConfig, ConfigError, TrackingSource};
use showcase_proto::{Role, Showcase};
use showcase_render::net::{ClusterIdentity, TlsError, client_config, resolve, server_config};
use std::collections::HashSet;
use std::path::{Path, PathBuf};

/// One problem: the file it is in, what is wrong, what to do.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Problem {
    /// The file at fault, as the config names it (joined to its folder).
    pub file: String,
    /// What is wrong.
    pub problem: String,
    /// What to do about it.
    pub fix: String,
}

impl Problem {
    /// A problem in `file`; a leading `"<file>: "` in `problem` (errors
    /// that name their file) is dropped so the file is named once.
    fn new(file: impl Into<String>, problem: impl ToString, fix: impl Into<String>) -> Self {
        let file = file.into();
        let problem = problem.to_string();
        let problem = problem
            .strip_prefix(&format!("{file}: "))
            .map_or(problem.clone(), str::to_owned);
        Self {
            file,
            problem,
            fix: fix.into(),
        }
    }
}

impl std::fmt::Display for Problem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: {}. What to do: {}",
            self.file,
            self.problem.trim_end_matches('.'),
            self.fix
        )
    }
}

/// What [`check_cluster`] found.
#[derive(Clone, Debug, Default)]
pub struct CheckReport {
    /// Every problem, in the order checked (config, addresses, scene,
    /// nodes, certificates, tracking).
    pub problems: Vec<Problem>,
    /// What was checked, for the summary of a clean run.
    pub checked: Vec<String>,
}

/// Check the cluster config at `config` and everything it names.
pub fn check_cluster(config: &Path) -> CheckReport {
    let mut r = CheckReport::default();
    let label = config.display().to_string();
    let text = match std::fs::read_to_string(config) {
        Ok(t) => t,
        Err(e) => {
            r.problems.push(Problem::new(
                &label,
                format!("cannot read the cluster config: {e}"),
                "give the path of a cluster config (deploy/loopback.toml is an example)",
            ));
            return r;
        }
    };
    let cfg = match ClusterConfig::from_toml(&text, &label) {
        Ok(c) => c,
        Err(e) => {
            r.problems.push(Problem::new(
                &label,
                e,
                "correct it (deploy/cluster.toml shows every key); nothing else can be checked until the config parses",
            ));
            return r;
        }
    };
    r.problems.extend(
        cfg.problems(&label)
            .into_iter()
            .map(|e| config_problem(&label, e)),
    );
    let base = config.parent().unwrap_or(Path::new("."));
    r.problems.extend(address_problems(&cfg, &label));
    let (scene, names) = check_scene(&mut r, &scene_file::resolve(base, &cfg.master.scene));
    r.problems.extend(node_problems(
        &cfg,
        names.as_ref(),
        scene.as_ref(),
        base,
        &label,
    ));
    check_certs(&mut r, &cfg, &base.join(&cfg.master.certs));
    check_tracking(&mut r, &cfg, names.as_ref(), scene.is_some(), base, &label);
    r.checked.insert(
        0,
        format!(
            "{label}: {} nodes, master on {}",
            cfg.nodes.len(),
            cfg.master.listen
        ),
    );
    dedup(&mut r.problems);
    r
}

/// The same problem found twice (a `ca.pem` every peer fails on) is
/// reported once.
fn dedup(problems: &mut Vec<Problem>) {
    let mut seen = HashSet::new();
    problems.retain(|p| seen.insert((p.file.clone(), p.problem.clone())));
}

/// A config problem with what to do about it.
fn config_problem(label: &str, e: ConfigError) -> Problem {
    let fix = match &e {
        ConfigError::Parse { .. } => {
            "correct the TOML (deploy/cluster.toml shows every key)".into()
        }
        ConfigError::UnknownNode { .. } => "use a name of a [[node]]".into(),
        ConfigError::DuplicateName { .. } => {
            "give every [[node]] its own name (it is also its certificate's name)".into()
        }
        ConfigError::DuplicateRole { .. } => {
            "let one node drive each output, or give one of them another output".into()
        }
        ConfigError::MissingCalibration { .. } => {
            "set calibration to a file made by `showcase-master calibrate`, or to \"scene\"".into()
        }
        ConfigError::PortClash { .. } => "give one of them another port".into(),
        ConfigError::Invalid { field, .. } => {
            format!("correct {field} (deploy/cluster.toml shows every key)")
        }
    };
    Problem::new(label, e, fix)
}

/// Every address resolves, as `run` and the nodes will resolve it.
fn address_problems(cfg: &ClusterConfig, label: &str) -> Vec<Problem> {
    let bind_keys: Vec<_> = cfg
        .nodes
        .iter()
        .filter_map(|n| Some((n.bind.as_ref()?, format!("node {:?}.bind", n.name))))
        .collect();
    std::iter::once((&cfg.master.listen, "master.listen".to_owned()))
        .chain(bind_keys)
        .filter_map(|(addr, key)| resolve(addr, &key).err())
        .map(|e| {
            Problem::new(
                label,
                format!(
                    "{}: cannot resolve host {:?} ({})",
                    e.source_text(),
                    e.host,
                    e.problem
                ),
                "check the name and this PC's DNS or /etc/hosts, or give an IP address",
            )
        })
        .collect()
}

/// The scene as far as it loads: the loaded scene and its names, or, when
/// it does not load, the names its file declares (with every mesh problem
/// reported on its own), or neither.
fn check_scene(r: &mut CheckReport, path: &Path) -> (Option<Showcase>, Option<SceneNames>) {
    let file = path.display().to_string();
    let fix = "correct the scene (its schema: master/src/scene_file/mod.rs)";
    match scene_file::load_any(path) {
        Ok(scene) => {
            r.checked.push(format!(
                "scene {file}: {} objects, {} faces, {} projectors, {} cameras, {} observers, {} lights",
                scene.objects.len(),
                scene.faces.len(),
                scene.projectors.len(),
                scene.cameras.len(),
                scene.observers.len(),
                scene.lights.len()
            ));
            let names = SceneNames::of(&scene);
            (Some(scene), Some(names))
        }
        Err(e) => match scene_file::outline(path) {
            Ok(outline) => {
                if outline.mesh_errors.is_empty() {
                    r.problems.push(Problem::new(&file, e, fix));
                } else {
                    r.problems.extend(outline.mesh_errors.into_iter().map(|m| {
                        Problem::new(
                            &file,
                            m,
                            "fix the mesh path (relative to the scene file) or the mesh file",
                        )
                    }));
                }
                (None, Some(outline.names))
            }
            Err(_) => {
                r.problems.push(Problem::new(&file, e, fix));
                (None, None)
            }
        },
    }
}

/// Every node's output is in the scene (when its names are known) and
/// every calibration file a node names reads as one. `run` stops on the
/// first of these.
pub(crate) fn node_problems(
    cfg: &ClusterConfig,
    names: Option<&SceneNames>,
    scene: Option<&Showcase>,
    base: &Path,
    label: &str,
) -> Vec<Problem> {
    let mut out = Vec::new();
    for n in &cfg.nodes {
        if let Some(names) = names {
            let list = match n.role {
                Role::Face => &names.faces,
                Role::Projector => &names.projectors,
                Role::Camera => &names.cameras,
            };
            if !list.contains(&n.output) {
                out.push(Problem::new(
                    label,
                    format!(
                        "node {:?} drives {} {:?}, which the scene does not have",
                        n.name, n.role, n.output
                    ),
                    format!("set its output to one of the scene's {}s: {list:?}", n.role),
                ));
            }
        }
        let Some(c) = n.calibration.as_deref().filter(|c| *c != "scene") else {
            continue;
        };
        let path = base.join(c);
        let fix = "make it with `showcase-master calibrate --points POINTS.json --out FILE`, \
                   or set the node's calibration to \"scene\"";
        if !path.is_file() {
            out.push(Problem::new(
                path.display().to_string(),
                format!("missing: node {:?}'s calibration in {label}", n.name),
                fix,
            ));
            continue;
        }
        let size = scene.and_then(|s| {
            let dev = match n.role {
                Role::Projector => &s.projectors.iter().find(|p| p.name == n.output)?.device,
                Role::Camera => &s.cameras.iter().find(|c| c.name == n.output)?.device,
                Role::Face => return None,
            };
            Some((dev.width, dev.height))
        });
        if let Err(e) =
            scene_file::read_calibration(&path, label, &format!("node {:?}", n.name), size)
        {
            out.push(Problem::new(path.display().to_string(), e, fix));
        }
    }
    out
}

/// `ca.pem`, and the master's and each node's certificate and key: present,
/// signed by the CA, valid now, issued to the peer's name, and accepted by
/// the TLS configuration that peer will build.
fn check_certs(r: &mut CheckReport, cfg: &ClusterConfig, dir: &Path) {
    let mut names: Vec<&str> = Vec::new();
    for n in &cfg.nodes {
        if !names.contains(&n.name.as_str()) {
            names.push(&n.name);
        }
    }
    let certs_cmd = format!(
        "`showcase-master certs --out {}{}`",
        dir.display(),
        names
            .iter()
            .map(|n| format!(" --node {n}"))
            .collect::<String>()
    );
    let ca = dir.join("ca.pem");
    if !ca.is_file() {
        let problem = if dir.is_dir() {
            "missing: there is no cluster CA".to_owned()
        } else {
            format!(
                "missing: the certificates folder {} does not exist",
                dir.display()
            )
        };
        r.problems.push(Problem::new(
            ca.display().to_string(),
            problem,
            format!("make the cluster's certificates with {certs_cmd} and copy them to every PC"),
        ));
        return;
    }
    let now = rustls::pki_types::UnixTime::now();
    let reissue = format!(
        "issue the certificates again with {certs_cmd} (that makes a new CA: copy every file to every PC)"
    );
    let peers = std::iter::once((
        crate::certs::MASTER_FILE,
        crate::certs::MASTER_SERVER_NAME,
        true,
    ))
    .chain(names.iter().map(|n| (*n, *n, false)));
    let mut ok = 0;
    for (stem, name, server) in peers {
        let cert = dir.join(format!("{stem}.pem"));
        let key = dir.join(format!("{stem}.key"));
        if let Some(missing) = [&cert, &key].into_iter().find(|p| !p.is_file()) {
            r.problems.push(Problem::new(
                missing.display().to_string(),
                format!("missing: {name}'s certificate and key"),
                &reissue,
            ));
            continue;
        }
        let id = match ClusterIdentity::load(dir, stem) {
            Ok(id) => id,
            Err(TlsError::Pem { path, problem }) => {
                r.problems
                    .push(Problem::new(path.display().to_string(), problem, &reissue));
                continue;
            }
            Err(e) => {
                r.problems
                    .push(Problem::new(cert.display().to_string(), e, &reissue));
                continue;
            }
        };
        if let Err(p) = id.verify(name, server, now) {
            let fix = if p.reissue { reissue.clone() } else { p.fix };
            r.problems
                .push(Problem::new(cert.display().to_string(), p.problem, fix));
            continue;
        }
        let tls = if server {
            server_config(&id).err()
        } else {
            client_config(&id).err()
        };
        if let Some(e) = tls {
            r.problems.push(Problem::new(
                key.display().to_string(),
                format!("does not go with {}: {e}", cert.display()),
                &reissue,
            ));
            continue;
        }
        ok += 1;
    }
    r.checked.push(format!(
        "certificates in {}: {ok} peers signed by ca.pem and named right",
        dir.display()
    ));
}

/// Body targets name what the scene has; a recording source reads.
fn check_tracking(
    r: &mut CheckReport,
    cfg: &ClusterConfig,
    names: Option<&SceneNames>,
    loaded: bool,
    base: &Path,
    label: &str,
) {
    let Some(t) = &cfg.tracking else {
        return;
    };
    if let Some(names) = names {
        for b in &t.bodies {
            // A scene that did not load lists its objects without their
            // parts: `object:room/floor` cannot be checked then.
            let unknown_part = !loaded
                && b.target
                    .strip_prefix("object:")
                    .and_then(|o| o.split_once('/'))
                    .is_some_and(|(o, _)| names.objects.iter().any(|n| n == o));
            if unknown_part {
                continue;
            }
            if let Err(problem) = resolve_target(&b.target, names) {
                let known = format!(
                    "observers {:?}, lights {:?}, objects {:?}",
                    names.observers, names.lights, names.objects
                );
                r.problems.push(Problem::new(
                    label,
                    format!("tracking body {}: {problem}", b.id),
                    format!("map it to one the scene has: {known}"),
                ));
            }
        }
    }
    if let (TrackingSource::Recording, Some(file)) = (t.source, &t.file) {
        let path: PathBuf = base.join(file);
        if let Err(e) = recording::read(&path) {
            r.problems.push(Problem::new(
                path.display().to_string(),
                e,
                "record a session with `showcase-master run --record FILE`, or correct tracking.file",
            ));
        }
    }
    r.checked
        .push(format!("tracking: {} bodies mapped", t.bodies.len()));
}
