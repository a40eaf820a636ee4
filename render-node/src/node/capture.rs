//! A node's capture devices: what a projector node shows and what a camera
//! node captures when the master asks (`ShowPattern`, `CaptureFrames`),
//! behind [`CaptureDevices`]; and the simulated ones.
//!
//! # The sim's light
//! In sim mode each node holds the sim device of its output. A projector
//! node's [`BusProjector`] publishes what it shows to a [`LightBus`], which
//! stands for the room: the light that leaves a projector. A camera node's
//! [`SimCameraNode`] holds the simulated showcase of the scene it was sent
//! and, at each capture, lights it with what the bus says every projector
//! is showing (black for one that shows nothing), so a camera sees only
//! what the projector nodes actually show, as a real camera would: the
//! master never tells the camera what is shown. The bus is memory shared
//! by the tasks of one process (loopback clusters) or a folder shared by
//! processes on one machine, where each projector's image is replaced
//! atomically (written aside, then renamed).

use showcase_light::hardware::{CameraDevice, CameraFrame, ProjectorDevice};
use showcase_light::sim::{SimCamera, SimConfig, SimError, SimShowcase};
use showcase_light::{Image, RgbImage};
use showcase_proto::capture::{CaptureFrames, Pattern};
use showcase_proto::{PinholeDevice, Showcase};
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

/// What a node does for the master's capture requests. Errors are words
/// for the master's operator (they travel back in `CaptureFailed`).
pub trait CaptureDevices: Send {
    /// The scene changed (a simulated world follows it).
    fn set_scene(&mut self, scene: Arc<Showcase>);
    /// Show `pattern` until the next one (a projector node).
    fn show(&mut self, pattern: &Pattern) -> Result<(), String>;
    /// Capture the frames `request` asks for (a camera node).
    fn capture(&mut self, request: &CaptureFrames) -> Result<Vec<CameraFrame>, String>;
}

/// A node's capture devices, shared with the blocking thread a request
/// runs on.
#[derive(Clone)]
pub struct CaptureHost(pub Arc<Mutex<Box<dyn CaptureDevices>>>);

impl CaptureHost {
    /// Host `devices`.
    pub fn new(devices: impl CaptureDevices + 'static) -> Self {
        Self(Arc::new(Mutex::new(Box::new(devices))))
    }
}

impl std::fmt::Debug for CaptureHost {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("CaptureHost")
    }
}

/// The room's light in sim mode: what each projector (by name) shows.
#[derive(Clone, Debug)]
pub enum LightBus {
    /// Shared by the tasks of one process.
    Memory(Arc<Mutex<HashMap<String, RgbImage>>>),
    /// A folder shared by processes: `<projector>.light`, replaced
    /// atomically.
    Dir(PathBuf),
}

const MAGIC: &[u8; 8] = b"SCLIGHT1";

impl LightBus {
    /// A bus in memory.
    pub fn memory() -> Self {
        LightBus::Memory(Arc::default())
    }

    /// Projector `name` shows `image`.
    pub fn publish(&self, name: &str, image: &RgbImage) -> Result<(), String> {
        match self {
            LightBus::Memory(m) => {
                m.lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .insert(name.to_string(), image.clone());
                Ok(())
            }
            LightBus::Dir(dir) => {
                let mut bytes = Vec::with_capacity(16 + image.data.len() * 12);
                bytes.extend_from_slice(MAGIC);
                bytes.extend_from_slice(&image.width.to_le_bytes());
                bytes.extend_from_slice(&image.height.to_le_bytes());
                for v in &image.data {
                    for c in v.to_array() {
                        bytes.extend_from_slice(&c.to_le_bytes());
                    }
                }
                let path = dir.join(format!("{name}.light"));
                let tmp = dir.join(format!(".{name}.light.tmp"));
                std::fs::write(&tmp, &bytes)
                    .and_then(|_| std::fs::rename(&tmp, &path))
                    .map_err(|e| format!("sim light bus {}: {e}", path.display()))
            }
        }
    }

    /// What projector `name` shows (`None`: nothing yet).
    pub fn read(&self, name: &str) -> Result<Option<RgbImage>, String> {
        match self {
            LightBus::Memory(m) => Ok(m
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .get(name)
                .cloned()),
            LightBus::Dir(dir) => {
                let path = dir.join(format!("{name}.light"));
                let bytes = match std::fs::read(&path) {
                    Ok(b) => b,
                    Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
                    Err(e) => return Err(format!("sim light bus {}: {e}", path.display())),
                };
                let bad = || format!("sim light bus {}: not a light file", path.display());
                if bytes.len() < 16 || &bytes[..8] != MAGIC {
                    return Err(bad());
                }
                let w = u32::from_le_bytes(bytes[8..12].try_into().map_err(|_| bad())?);
                let h = u32::from_le_bytes(bytes[12..16].try_into().map_err(|_| bad())?);
                let body = &bytes[16..];
                if body.len() != w as usize * h as usize * 12 {
                    return Err(bad());
                }
                let data = body
                    .chunks_exact(12)
                    .map(|p| {
                        glam::Vec3::from_array(std::array::from_fn(|k| {
                            f32::from_le_bytes(p[4 * k..4 * k + 4].try_into().expect("4 bytes"))
                        }))
                    })
                    .collect();
                Ok(Some(Image {
                    width: w,
                    height: h,
                    data,
                }))
            }
        }
    }
}

/// A simulated projector on a node: shows by publishing its image to the
/// light bus.
#[derive(Clone, Debug)]
pub struct BusProjector {
    name: String,
    device: PinholeDevice,
    period_s: f64,
    bus: LightBus,
}

impl BusProjector {
    /// Projector `name` of `scene`, publishing to `bus`.
    pub fn new(scene: &Showcase, name: &str, bus: LightBus) -> Result<Self, String> {
        let p = scene
            .projectors
            .iter()
            .find(|p| p.name == name)
            .ok_or_else(|| format!("the scene has no projector {name:?}"))?;
        Ok(Self {
            name: name.into(),
            device: p.device.clone(),
            period_s: if p.response.wheel_segments.is_empty() {
                0.0
            } else {
                p.response.wheel_period_s as f64
            },
            bus,
        })
    }
}

/// Why a simulated node device failed.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BusError(String);

impl ProjectorDevice for BusProjector {
    type Error = BusError;
    fn device(&self) -> &PinholeDevice {
        &self.device
    }
    fn show(&mut self, image: &RgbImage) -> Result<(), BusError> {
        let d = &self.device;
        if (image.width, image.height) != (d.width, d.height) {
            return Err(BusError(format!(
                "projector {:?} is {}x{}, the pattern is {}x{}",
                self.name, d.width, d.height, image.width, image.height
            )));
        }
        let clamped = image.map(|v| v.clamp(glam::Vec3::ZERO, glam::Vec3::ONE));
        self.bus.publish(&self.name, &clamped).map_err(BusError)
    }
    fn wheel_period_s(&self) -> f64 {
        self.period_s
    }
}

/// A projector node's sim device.
#[derive(Debug)]
pub struct SimProjectorNode {
    name: String,
    bus: LightBus,
    projector: Option<BusProjector>,
}

impl SimProjectorNode {
    /// The node of projector `name`, publishing to `bus`.
    pub fn new(name: &str, bus: LightBus) -> Self {
        Self {
            name: name.into(),
            bus,
            projector: None,
        }
    }
}

impl CaptureDevices for SimProjectorNode {
    fn set_scene(&mut self, scene: Arc<Showcase>) {
        self.projector = BusProjector::new(&scene, &self.name, self.bus.clone()).ok();
    }
    fn show(&mut self, pattern: &Pattern) -> Result<(), String> {
        let p = self.projector.as_mut().ok_or_else(|| {
            format!(
                "the scene has no projector {:?}: check this node's output in the cluster config",
                self.name
            )
        })?;
        p.show_pattern(pattern).map_err(|e| e.to_string())
    }
    fn capture(&mut self, _: &CaptureFrames) -> Result<Vec<CameraFrame>, String> {
        Err(format!(
            "{:?} is a projector node; captures need a camera node",
            self.name
        ))
    }
}

/// A camera node's sim device: the simulated showcase of the current
/// scene, lit from the light bus at each capture.
pub struct SimCameraNode {
    name: String,
    bus: LightBus,
    config: SimConfig,
    scene: Option<Arc<Showcase>>,
    sim: Option<(SimShowcase, SimCamera)>,
}

impl std::fmt::Debug for SimCameraNode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "SimCameraNode({})", self.name)
    }
}

impl SimCameraNode {
    /// The node of camera `name`, reading `bus`, with the sim's `config`.
    pub fn new(name: &str, bus: LightBus, config: SimConfig) -> Self {
        Self {
            name: name.into(),
            bus,
            config,
            scene: None,
            sim: None,
        }
    }

    fn sim(&mut self) -> Result<&mut (SimShowcase, SimCamera), String> {
        if self.sim.is_none() {
            let scene = self
                .scene
                .as_ref()
                .ok_or("no scene yet: the master has not sent one")?;
            let index = scene
                .cameras
                .iter()
                .position(|c| c.name == self.name)
                .ok_or_else(|| {
                    format!(
                        "the scene has no camera {:?}: check this node's output in the cluster config",
                        self.name
                    )
                })?;
            let sim = SimShowcase::new(scene, self.config.clone()).map_err(|e| e.to_string())?;
            let camera = sim.camera(index).map_err(|e| e.to_string())?;
            self.sim = Some((sim, camera));
        }
        Ok(self.sim.as_mut().expect("built above"))
    }
}

impl CaptureDevices for SimCameraNode {
    fn set_scene(&mut self, scene: Arc<Showcase>) {
        // A new world only when what exists or where changed; a version
        // bump for new maps keeps the world (and its light transport).
        let same = self.scene.as_ref().is_some_and(|s| {
            s.objects == scene.objects
                && s.meshes == scene.meshes
                && s.projectors == scene.projectors
                && s.cameras == scene.cameras
        });
        self.scene = Some(scene);
        if !same {
            self.sim = None;
        }
    }
    fn show(&mut self, _: &Pattern) -> Result<(), String> {
        Err(format!(
            "{:?} is a camera node; patterns need a projector node",
            self.name
        ))
    }
    fn capture(&mut self, request: &CaptureFrames) -> Result<Vec<CameraFrame>, String> {
        let bus = self.bus.clone();
        let scene = self.scene.clone().ok_or("no scene yet")?;
        let (sim, camera) = self.sim()?;
        // The room's light now: what each projector node shows.
        for (i, p) in scene.projectors.iter().enumerate() {
            let image = bus
                .read(&p.name)?
                .unwrap_or_else(|| Image::new(p.device.width, p.device.height, glam::Vec3::ZERO));
            sim.projector(i)
                .and_then(|mut d| d.show(&image))
                .map_err(|e: SimError| format!("projector {:?}'s light: {e}", p.name))?;
        }
        camera.set_gain(request.gain as f32);
        camera.set_exposure(request.exposure_s as f32);
        camera
            .capture_series(request.exposure_s, request.period_s, request.count)
            .map_err(|e| e.to_string())
    }
}
