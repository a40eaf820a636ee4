//! A camera node backed by a recorded camera (`showcase-node --camera
//! recorded:DIR`): a loopback cluster (master, sim projector node, camera
//! node as tasks, QUIC over 127.0.0.1) first records the sim camera node's
//! frames of a naive capture, then runs the same capture with a camera node
//! replaying that folder through `CameraNode<RecordedCamera>`: the same
//! reflectance map, bit for bit (the replayed codes are the recorded ones,
//! the PNGs hold the codes exactly, and the master's pipeline is
//! deterministic). The recording, its exposures changed, then stops the
//! capture with the node's name and why. Small: figure 3 with a 40 x 30
//! camera, 128 x 96 projectors, 4 frames a capture.

use showcase_light::hardware::{CameraDevice, CameraFrame};
use showcase_light::sim::SimConfig;
use showcase_master::capture::cluster::{
    ClusterCaptureOptions, ClusterCaptureSummary, run_cluster_capture,
};
use showcase_master::capture::pipeline::{CaptureConfig, EtaMode, Method};
use showcase_master::capture::{resize_device, with_capture_rig};
use showcase_master::certs::{self, MASTER_FILE};
use showcase_master::cluster::capture_link::CaptureLink;
use showcase_master::cluster::{Roster, Server, ServerSettings, Show, Tracking};
use showcase_proto::capture::{CaptureFrames, Pattern};
use showcase_proto::session::MasterConfig;
use showcase_proto::{Role, Showcase};
use showcase_render::camera::TimedFrame;
use showcase_render::camera::recorded::{INDEX, RecordedCamera, Recorder, RecordingIndex};
use showcase_render::net::ClusterIdentity;
use showcase_render::node::{
    CameraNode, CaptureDevices, CaptureHost, LightBus, NodeRuntime, SimCameraNode,
    SimProjectorNode, StateHashRenderer, run_node_with_devices,
};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio_util::sync::CancellationToken;

const SAMPLES: u32 = 8;

fn figure3() -> Showcase {
    let scene = showcase_master::scene_file::load_any(Path::new("builtin:figure3"))
        .expect("the built-in figure-3 scene");
    let mut scene = with_capture_rig(&scene, Some((40, 30))).unwrap();
    for p in &mut scene.projectors {
        p.device = resize_device(&p.device, 128, 96).unwrap();
    }
    scene
}

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("showcase-{name}-{}", std::process::id()));
    std::fs::remove_dir_all(&d).ok();
    d
}

fn sim() -> SimConfig {
    SimConfig {
        samples_per_pixel: SAMPLES,
        ..SimConfig::default()
    }
}

/// The sim camera node, recording every frame it sends.
struct Recording {
    inner: SimCameraNode,
    name: String,
    scene: Option<Arc<Showcase>>,
    recorder: Arc<Mutex<Option<Recorder>>>,
    dir: PathBuf,
    clock_s: f64,
}

impl CaptureDevices for Recording {
    fn set_scene(&mut self, scene: Arc<Showcase>) {
        self.scene = Some(scene.clone());
        self.inner.set_scene(scene)
    }
    fn show(&mut self, pattern: &Pattern) -> Result<(), String> {
        self.inner.show(pattern)
    }
    fn capture(&mut self, r: &CaptureFrames) -> Result<Vec<CameraFrame>, String> {
        let frames = self.inner.capture(r)?;
        let mut slot = self.recorder.lock().unwrap();
        if slot.is_none() {
            let scene = self.scene.as_ref().ok_or("no scene")?;
            let cam = scene.cameras.iter().find(|c| c.name == self.name).unwrap();
            // The gain the frames were taken with: the master's (in sim
            // mode it sets the gain from the sim, as the in-process
            // capture does).
            let response = showcase_proto::CameraResponse {
                gain: r.gain as f32,
                ..cam.response.clone()
            };
            *slot = Some(
                Recorder::create(&self.dir, cam.device.clone(), response)
                    .map_err(|e| e.to_string())?,
            );
        }
        let rec = slot.as_mut().expect("created above");
        for (k, f) in frames.iter().enumerate() {
            rec.push(&TimedFrame {
                frame: f.clone(),
                timestamp_s: self.clock_s + r.start_s(k as u32),
                start_of_exposure: true,
                sequence: 0,
                exposure_s: r.exposure_s,
            })
            .map_err(|e| e.to_string())?;
        }
        self.clock_s += 10.0;
        Ok(frames)
    }
}

fn identity(c: &certs::ClusterCerts, name: &str) -> ClusterIdentity {
    let p = c.peers.iter().find(|p| p.name == name).unwrap();
    ClusterIdentity::from_pem(&c.ca_pem, &p.cert_pem, &p.key_pem).unwrap()
}

/// A naive capture of `scene` through a loopback cluster whose camera
/// node holds `camera(bus)`; the job's summary or its error (with its
/// chain, as the CLI prints it).
fn capture_with(
    scene: &Showcase,
    out: &Path,
    camera: impl FnOnce(LightBus) -> CaptureHost,
) -> Result<ClusterCaptureSummary, String> {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        let pname = scene.projectors[0].name.clone();
        let cname = scene.cameras[0].name.clone();
        let nodes = [
            (pname.clone(), Role::Projector),
            (cname.clone(), Role::Camera),
        ];
        let names: Vec<String> = nodes.iter().map(|(n, _)| n.clone()).collect();
        let c = certs::generate(&names).unwrap();
        let (link, commands) = CaptureLink::new(Duration::from_secs(120));
        let server = Server::bind(ServerSettings::capture(
            "127.0.0.1:0".parse().unwrap(),
            identity(&c, MASTER_FILE),
            Roster::new(nodes.iter().cloned()),
            2,
        ))
        .unwrap()
        .capture_from(commands);
        let addr = server.local_addr();
        let stop = CancellationToken::new();
        let show = Show::new(Tracking::None, MasterConfig::default().target_hz as f64);
        let master = tokio::spawn(server.run(scene.clone(), show, stop.clone()));
        let bus = LightBus::memory();
        let mut tasks = Vec::new();
        for (name, role, devices) in [
            (
                &pname,
                Role::Projector,
                CaptureHost::new(SimProjectorNode::new(&pname, bus.clone())),
            ),
            (&cname, Role::Camera, camera(bus.clone())),
        ] {
            let node = NodeRuntime {
                name: name.clone(),
                role,
                master: addr,
                identity: identity(&c, name),
                bind: "127.0.0.1:0".parse().unwrap(),
                capabilities: Default::default(),
                write_frames: None,
                keep_presented: false,
            };
            let token = CancellationToken::new();
            let t = token.clone();
            let n = name.clone();
            tasks.push((
                tokio::spawn(async move {
                    let mut r = StateHashRenderer::new(&n, role);
                    run_node_with_devices(node, &mut r, Some(devices), t).await
                }),
                token,
            ));
        }
        let options = ClusterCaptureOptions {
            methods: vec![Method::Naive],
            capture: CaptureConfig {
                frames: 4,
                method: Method::Naive,
                eta: EtaMode::FromScene,
                reference_samples: SAMPLES,
                ..CaptureConfig::default()
            },
            sim: Some(sim()),
            wait: Duration::from_secs(10),
        };
        let (scene, out) = (scene.clone(), out.to_path_buf());
        let summary = tokio::task::spawn_blocking(move || {
            run_cluster_capture(&scene, &link, &pname, &cname, &out, &options, &|_| {})
                .map_err(|e| format!("{e:#}"))
        })
        .await
        .unwrap();
        stop.cancel();
        for (task, token) in tasks {
            token.cancel();
            let _ = tokio::time::timeout(Duration::from_secs(10), task).await;
        }
        let _ = tokio::time::timeout(Duration::from_secs(10), master).await;
        summary
    })
}

/// Record the sim camera node's frames of a naive capture, replay them
/// through a recorded-camera node: the same map, bit for bit. Then the
/// recording with other exposures: the master's error names the node and
/// says a recorded camera cannot change its exposure.
#[test]
fn a_recorded_camera_node_replays_a_capture_to_the_same_map() {
    let scene = figure3();
    let cname = scene.cameras[0].name.clone();
    let recording = dir("camnode-recording");
    let recorder = Arc::new(Mutex::new(None));
    let sim_out = dir("camnode-sim");
    let (name, rec, rdir) = (cname.clone(), recorder.clone(), recording.clone());
    let recorded = capture_with(&scene, &sim_out, move |bus| {
        CaptureHost::new(Recording {
            inner: SimCameraNode::new(&name, bus, sim()),
            name,
            scene: None,
            recorder: rec,
            dir: rdir,
            clock_s: 0.0,
        })
    })
    .unwrap();
    let rec = recorder
        .lock()
        .unwrap()
        .take()
        .expect("frames were recorded");
    rec.finish().unwrap();
    let frames = RecordedCamera::open(&recording)
        .unwrap()
        .index()
        .frames
        .len();
    assert_eq!(frames as u64, recorded.frames, "{recorded:?}");

    let replay_out = dir("camnode-replay");
    let name = cname.clone();
    let camera = RecordedCamera::open(&recording).unwrap();
    assert_eq!(camera.device().width, 40);
    let replayed = capture_with(&scene, &replay_out, move |_| {
        CaptureHost::new(CameraNode::new(&name, camera))
    })
    .unwrap();
    assert_eq!(replayed.frames, recorded.frames);
    let map = "reflectance-naive.pfm";
    let (a, b) = (
        std::fs::read(sim_out.join(map)).unwrap(),
        std::fs::read(replay_out.join(map)).unwrap(),
    );
    assert!(
        a == b,
        "the replayed map differs from the recorded capture's"
    );
    assert_eq!(replayed.methods[0].rel_rmse, recorded.methods[0].rel_rmse);

    // The same recording, taken (it says) at twice the exposure.
    let path = recording.join(INDEX);
    let mut index: RecordingIndex =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    for f in &mut index.frames {
        f.exposure_s *= 2.0;
    }
    std::fs::write(&path, serde_json::to_string(&index).unwrap()).unwrap();
    let camera = RecordedCamera::open(&recording).unwrap();
    let name = cname.clone();
    let e = capture_with(&scene, &dir("camnode-exposure"), move |_| {
        CaptureHost::new(CameraNode::new(&name, camera))
    })
    .unwrap_err();
    assert!(e.contains(&format!("camera node {cname:?}")), "{e}");
    assert!(
        e.contains("a recorded camera cannot change its exposure") && e.contains("recorded with"),
        "{e}"
    );
    for d in [recording, sim_out, replay_out, dir("camnode-exposure")] {
        std::fs::remove_dir_all(d).ok();
    }
}
