//! `showcase-master check --config`: a good loopback cluster passes; a
//! config with mistakes of six kinds gets all six reported in one run,
//! each naming its file. The command runs as a child process
//! ([`crate::shutdown::master_process`]) for its exit status and output.

use crate::shutdown::master_process;
use showcase_master::certs;
use showcase_master::cluster::check::{Problem, check_cluster};
use showcase_master::cluster::faults::loopback_config;
use showcase_proto::Role;
use std::path::{Path, PathBuf};

/// The nodes of the test cluster: the demo cabinet's faces and projectors.
const NODES: [(&str, Role); 4] = [
    ("face-0", Role::Face),
    ("face-1", Role::Face),
    ("projector-0", Role::Projector),
    ("projector-1", Role::Projector),
];

/// A fresh folder with the demo cabinet's scene (mesh paths made
/// absolute, so the copy loads from here), certificates made by
/// `showcase-master certs`, and a loopback `cluster.toml`, edited by
/// `edit_scene` and `edit_config`.
fn cluster(
    test: &str,
    edit_scene: impl Fn(String) -> String,
    edit_config: impl Fn(String) -> String,
) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("showcase-check-{test}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    // The demo cabinet's file in the source tree (the binary's built-in
    // copy has no folder to copy next to).
    let scene_src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy/scenes/showcase.toml");
    let data = std::fs::canonicalize(scene_src.parent().unwrap().join("../../../shared/data"))
        .expect("the shared data folder (../shared/data)");
    let scene = std::fs::read_to_string(&scene_src)
        .unwrap()
        .replace("../../../shared/data", data.to_str().unwrap());
    let scene_path = dir.join("scene.toml");
    std::fs::write(&scene_path, edit_scene(scene)).unwrap();
    let mut args = vec!["certs", "--out", "certs"];
    for (n, _) in NODES {
        args.extend(["--node", n]);
    }
    let made = master_process(&args).current_dir(&dir).output().unwrap();
    assert!(made.status.success(), "{made:?}");
    let cfg = loopback_config(4433, &scene_path, "source = \"scripted\"", &NODES);
    std::fs::write(dir.join("cluster.toml"), edit_config(cfg)).unwrap();
    dir
}

/// `check --config` on `dir/cluster.toml`: exit status and the problem
/// lines (stdout lines with "What to do"), and stderr.
fn run_check(dir: &Path) -> (bool, Vec<String>, String, String) {
    let config = dir.join("cluster.toml");
    let out = master_process(&["check", "--config", config.to_str().unwrap()])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let problems = stdout
        .lines()
        .filter(|l| l.contains(". What to do: "))
        .map(str::to_owned)
        .collect();
    (
        out.status.success(),
        problems,
        stdout,
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The problem in `file` whose text contains `what`; fails listing all.
#[track_caller]
fn find<'a>(problems: &'a [Problem], file: &Path, what: &str) -> &'a Problem {
    let file = file.display().to_string();
    problems
        .iter()
        .find(|p| p.file == file && p.problem.contains(what))
        .unwrap_or_else(|| panic!("no problem in {file} with {what:?} among {problems:#?}"))
}

#[test]
fn a_good_cluster_passes_with_a_host_name_listen_address() {
    let dir = cluster("good", |s| s, |c| c.replace("\"127.0.0.1:", "\"localhost:"));
    assert!(
        std::fs::read_to_string(dir.join("cluster.toml"))
            .unwrap()
            .contains("listen = \"localhost:4433\"")
    );
    let report = check_cluster(&dir.join("cluster.toml"));
    assert!(report.problems.is_empty(), "{:#?}", report.problems);
    let (ok, problems, stdout, stderr) = run_check(&dir);
    assert!(ok, "check failed: {stdout}{stderr}");
    assert!(problems.is_empty(), "{problems:?}");
    let summary = stdout
        .lines()
        .find(|l| l.starts_with("ok: "))
        .unwrap_or_else(|| panic!("no ok line: {stdout}"));
    assert!(
        summary.contains("4 nodes, master on localhost:4433"),
        "{summary}"
    );
    assert!(summary.contains("5 peers signed by ca.pem"), "{summary}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn six_seeded_mistakes_are_reported_in_one_run() {
    let dir = cluster(
        "six",
        // 1. A mesh file that is not there.
        |s| s.replacen("/bunny.obj\"", "/no-such-bunny.obj\"", 1),
        |c| {
            c
                // 2. A tracking body on an observer the scene does not have.
                .replace(
                    "body = [{ id = 0, target = \"observer:observer-0\" }]",
                    "body = [{ id = 0, target = \"observer:observer-0\" }, \
                     { id = 1, target = \"observer:nobody\" }]",
                )
                // 3. Two nodes named alike.
                .replace(
                    "name = \"face-1\"\nrole = \"face\"",
                    "name = \"face-0\"\nrole = \"face\"",
                )
                // 4. A host that does not resolve.
                .replace(
                    "output = \"projector-1\"",
                    "output = \"projector-1\"\nbind = \"no-such-pc.invalid:4501\"",
                )
        },
    );
    let certs_dir = dir.join("certs");
    // 5. A node certificate from another CA.
    let foreign = certs::generate(&["projector-1".to_owned()]).unwrap();
    certs::write(&dir.join("foreign"), &foreign).unwrap();
    for ext in ["pem", "key"] {
        std::fs::copy(
            dir.join(format!("foreign/projector-1.{ext}")),
            certs_dir.join(format!("projector-1.{ext}")),
        )
        .unwrap();
    }
    // 6. A node holding another node's certificate (right CA, wrong name).
    for ext in ["pem", "key"] {
        std::fs::copy(
            certs_dir.join(format!("face-0.{ext}")),
            certs_dir.join(format!("projector-0.{ext}")),
        )
        .unwrap();
    }

    let config = dir.join("cluster.toml");
    let problems = check_cluster(&config).problems;
    assert_eq!(problems.len(), 6, "{problems:#?}");
    let scene = dir.join("scene.toml");
    let mesh = find(&problems, &scene, "no-such-bunny.obj");
    assert!(mesh.problem.contains("object[2] 'bunny'.mesh"), "{mesh:?}");
    find(
        &problems,
        &config,
        "tracking body 1: the scene has no observer named \"nobody\"",
    );
    find(&problems, &config, "node name \"face-0\" is used twice");
    let host = find(
        &problems,
        &config,
        "cannot resolve host \"no-such-pc.invalid\"",
    );
    assert!(
        host.problem.starts_with("node \"projector-1\".bind"),
        "{host:?}"
    );
    let ca = find(
        &problems,
        &certs_dir.join("projector-1.pem"),
        "not signed by the cluster CA",
    );
    // The fix is the command for this cluster's nodes (names once each).
    assert!(
        ca.fix.contains(&format!(
            "`showcase-master certs --out {} --node face-0 --node projector-0 --node projector-1`",
            certs_dir.display()
        )),
        "{ca:?}"
    );
    find(
        &problems,
        &certs_dir.join("projector-0.pem"),
        "issued to [\"face-0\"], not to \"projector-0\"",
    );
    for p in &problems {
        assert!(!p.fix.is_empty(), "{p:?} says nothing to do");
    }

    // The command prints the same six lines, a count, and fails.
    let (ok, lines, stdout, stderr) = run_check(&dir);
    assert!(!ok, "check passed: {stdout}");
    let expected: Vec<String> = problems.iter().map(ToString::to_string).collect();
    assert_eq!(lines, expected, "{stdout}");
    assert!(
        stderr.contains(&format!(
            "6 problems in {}: fix them and run check again",
            config.display()
        )),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn missing_certs_meshes_calibrations_and_recordings_each_say_what_to_do() {
    let dir = cluster(
        "missing",
        // Each missing mesh is its own problem.
        |s| {
            s.replacen("/bunny.obj\"", "/gone-1.obj\"", 1).replacen(
                "/bunny.obj\"",
                "/gone-2.obj\"",
                1,
            )
        },
        |c| {
            c.replace("certs = \"certs\"", "certs = \"no-certs\"")
                .replace(
                    "source = \"scripted\"",
                    "source = \"recording\"\nfile = \"no-such-session.jsonl\"",
                )
                .replacen(
                    "calibration = \"scene\"",
                    "calibration = \"calib/projector-0.json\"",
                    1,
                )
                .replace("output = \"face-1\"", "output = \"face-9\"")
        },
    );
    let problems = check_cluster(&dir.join("cluster.toml")).problems;
    assert_eq!(problems.len(), 6, "{problems:#?}");
    let session = find(
        &problems,
        &dir.join("no-such-session.jsonl"),
        "No such file",
    );
    assert!(session.fix.contains("run --record"), "{session:?}");
    let scene = dir.join("scene.toml");
    find(&problems, &scene, "gone-1.obj");
    find(&problems, &scene, "gone-2.obj");
    let calib = find(
        &problems,
        &dir.join("calib/projector-0.json"),
        "missing: node \"projector-0\"'s calibration",
    );
    assert!(calib.fix.contains("showcase-master calibrate"), "{calib:?}");
    // The scene did not load, yet its declared faces are checked.
    let face = find(
        &problems,
        &dir.join("cluster.toml"),
        "node \"face-1\" drives face \"face-9\", which the scene does not have",
    );
    assert!(face.fix.contains("[\"face-0\", \"face-1\"]"), "{face:?}");
    // No certificates at all: one problem, with the command that makes them.
    let certs = find(
        &problems,
        &dir.join("no-certs/ca.pem"),
        "the certificates folder",
    );
    assert_eq!(
        certs.fix,
        format!(
            "make the cluster's certificates with `showcase-master certs --out {} \
             --node face-0 --node face-1 --node projector-0 --node projector-1` and copy them \
             to every PC",
            dir.join("no-certs").display()
        )
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn an_unparsable_config_is_one_problem_naming_the_line() {
    let dir = cluster(
        "syntax",
        |s| s,
        |c| c.replace("role = \"face\"", "role = \"wall\""),
    );
    let config = dir.join("cluster.toml");
    let problems = check_cluster(&config).problems;
    assert_eq!(problems.len(), 1, "{problems:#?}");
    let p = find(&problems, &config, "unknown variant `wall`");
    assert!(p.problem.contains("line"), "{p:?}");
    let missing = check_cluster(&dir.join("nope.toml")).problems;
    assert_eq!(missing.len(), 1, "{missing:#?}");
    find(
        &missing,
        &dir.join("nope.toml"),
        "cannot read the cluster config",
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_key_that_does_not_go_with_its_certificate_is_found() {
    let dir = cluster("key", |s| s, |c| c);
    let certs_dir = dir.join("certs");
    std::fs::copy(certs_dir.join("face-0.key"), certs_dir.join("face-1.key")).unwrap();
    let problems = check_cluster(&dir.join("cluster.toml")).problems;
    assert_eq!(problems.len(), 1, "{problems:#?}");
    find(&problems, &certs_dir.join("face-1.key"), "does not go with");
    std::fs::remove_dir_all(&dir).unwrap();
}
