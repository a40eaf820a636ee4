//! Cluster messages (DESIGN section 5). Every message is validated after
//! decoding; see [`crate::validate`].

use crate::scene::{FrameState, Showcase};
use serde::{Deserialize, Serialize};

/// What a render node drives.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// A CRT face: a stereo observer view through the beam splitter.
    Face,
    /// A projector: the irradiance map for that projector.
    Projector,
    /// A camera: capture only.
    Camera,
}

impl std::fmt::Display for Role {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Role::Face => "face",
            Role::Projector => "projector",
            Role::Camera => "camera",
        })
    }
}

/// What a node can do.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Capabilities {
    /// The node renders on a GPU (else on the CPU reference renderer).
    pub gpu: bool,
    /// Name of the adapter in use, for reports.
    pub adapter: String,
}

/// First message of a node.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Hello {
    /// Must equal [`crate::PROTOCOL_VERSION`].
    pub protocol_version: u32,
    /// The node's configured name (also in its certificate).
    pub node: String,
    /// Output it drives.
    pub role: Role,
    /// What it can do.
    pub capabilities: Capabilities,
}

/// The master's answer to [`Hello`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Welcome {
    /// The master's protocol version.
    pub protocol_version: u32,
    /// Target frame rate.
    pub target_hz: f32,
    /// Swap-barrier deadline in milliseconds after a frame is sent.
    pub deadline_ms: f32,
}

/// The full scene, sent on join, rejoin and whenever the scene changes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneSnapshot {
    /// Scene version; frames refer to it.
    pub version: u64,
    /// The scene.
    pub showcase: Showcase,
    /// The frame in flight when the snapshot was taken, for late joiners.
    pub current: Option<FrameState>,
    /// The captured reflectance maps of this scene version (a capture
    /// through the cluster bumps the version and sends them).
    pub maps: Vec<crate::capture::CapturedMap>,
}

/// A node has rendered a frame and is waiting to present it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Ready {
    /// The frame rendered.
    pub frame: u64,
    /// A hash of the rendered output, for replay checks.
    pub output_hash: u64,
}

/// Present a frame now.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Swap {
    /// The frame to present.
    pub frame: u64,
}

/// Per-frame measurements from a node, reported after presenting.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct NodeStats {
    /// The frame measured.
    pub frame: u64,
    /// Render time in milliseconds.
    pub render_ms: f32,
    /// Time between sending Ready and receiving Swap, in milliseconds.
    pub barrier_wait_ms: f32,
    /// Present time on the node's clock (ns).
    pub present_time_ns: u64,
}

/// NTP-style clock probe from the master.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ClockProbe {
    /// Probe sequence number.
    pub id: u64,
    /// Master clock when sent (ns).
    pub master_send_ns: u64,
}

/// A node's answer to a [`ClockProbe`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ClockReply {
    /// The probe answered.
    pub id: u64,
    /// Echo of the probe's master send time (ns).
    pub master_send_ns: u64,
    /// Node clock when the probe arrived (ns).
    pub node_recv_ns: u64,
    /// Node clock when this reply was sent (ns).
    pub node_send_ns: u64,
}

/// Orderly goodbye, with the reason.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Bye {
    /// Why the sender is leaving or closing the peer.
    pub reason: String,
}

/// Most elements a global-illumination solution may have (the radiosity
/// mesh's own default limit); 24 MB of values, within the codec's frame.
pub const MAX_ILLUMINATION_ELEMENTS: usize = 2_000_000;

/// Largest magnitude of a solution value (W/m^2): far above any real
/// irradiance, far below where f32 arithmetic on the GPU overflows.
pub const MAX_ILLUMINATION_VALUE: f32 = 1e6;

/// How the real surfaces are meshed for a global-illumination solution:
/// the radiosity mesh options a node meshes its scene with to read the
/// solution's per-element values (`showcase_light::radiosity::MeshOptions`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct IlluminationMesh {
    /// Largest patch area (m^2).
    pub max_patch_area: f64,
    /// Element subdivisions per patch.
    pub element_depth: u32,
    /// Smallest element area (m^2).
    pub min_element_area: f64,
}

/// Master to node: one version of the global-illumination solution, per
/// element of the scene's radiosity mesh ([`ElementLight`]). Frames name the version they are drawn with
/// ([`FrameState::illumination_version`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Illumination {
    /// The solution's version (increasing).
    pub version: u64,
    /// The scene version it was solved for (its mesh is that scene's).
    pub scene_version: u64,
    /// The values, whole or as changes.
    pub body: IlluminationBody,
}

/// A solution whole, or what changed since an earlier version.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum IlluminationBody {
    /// Every element's value.
    Full {
        /// How the scene is meshed.
        mesh: IlluminationMesh,
        /// Per element.
        values: Vec<ElementLight>,
    },
    /// The elements that differ from version `base`, in increasing element
    /// order; the others keep `base`'s value.
    Delta {
        /// The version this applies to.
        base: u64,
        /// The changed elements.
        changes: Vec<ElementChange>,
    },
}

/// One element's new value in an [`IlluminationBody::Delta`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ElementChange {
    /// Its index in the mesh.
    pub element: u32,
    /// Its light.
    pub value: ElementLight,
}

/// One element's global-illumination light (W/m^2, rgb).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ElementLight {
    /// What the displays add to the direct light there: on a virtual
    /// element (the faces) its indirect irradiance, on a real one (the
    /// projectors) what the target's indirect light has beyond the real
    /// surfaces' own interreflection.
    pub add: [f32; 3],
    /// What the real surfaces' own interreflection brings a real element
    /// (0 on virtual ones): the light it still reflects where the
    /// projectors leave it dark, seen through the virtual objects in
    /// front of it.
    pub cabinet: [f32; 3],
}

impl ElementLight {
    /// Its six numbers: `add`, then `cabinet`.
    pub fn channels(&self) -> impl Iterator<Item = f32> + '_ {
        self.add.iter().chain(&self.cabinet).copied()
    }
}

/// Node to master: the node lacks solution `version` (a delta's base never
/// came, or a frame names a version it was not sent); send full copies of
/// it and the newer ones.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct IlluminationResync {
    /// The first version the node lacks.
    pub version: u64,
}

/// Node to master: the node holds solution `version` and has prepared it
/// (made what drawing with it needs). The master names a new version in
/// frames once every live node holds it, so no frame waits for a
/// solution to cross the network or be prepared.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct IlluminationReady {
    /// The version.
    pub version: u64,
}

/// Every message of the cluster protocol.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Message {
    /// Node to master: join.
    Hello(Hello),
    /// Master to node: accepted.
    Welcome(Welcome),
    /// Master to node: the full scene.
    SceneSnapshot(Box<SceneSnapshot>),
    /// Master to node: the state of one frame.
    FrameState(Box<crate::scene::FrameState>),
    /// Node to master: frame rendered.
    Ready(Ready),
    /// Master to node: present the frame.
    Swap(Swap),
    /// Node to master: measurements.
    NodeStats(NodeStats),
    /// Master to node: clock probe.
    ClockProbe(ClockProbe),
    /// Node to master: clock reply.
    ClockReply(ClockReply),
    /// Master to node: a global-illumination solution, whole or a delta.
    Illumination(Box<Illumination>),
    /// Node to master: send full solutions from this version on.
    IlluminationResync(IlluminationResync),
    /// Master to projector node: show a pattern (capture).
    ShowPattern(Box<crate::capture::ShowPattern>),
    /// Projector node to master: the pattern is showing.
    PatternShown(crate::capture::PatternShown),
    /// Master to camera node: capture frames.
    CaptureFrames(crate::capture::CaptureFrames),
    /// Camera node to master: a piece of a captured frame.
    FrameChunk(Box<crate::capture::FrameChunk>),
    /// Node to master: a capture request failed.
    CaptureFailed(crate::capture::CaptureFailed),
    /// Either way: leaving.
    Bye(Bye),
    /// Node to master: a solution is held and prepared.
    IlluminationReady(IlluminationReady),
}

impl Message {
    /// A short name for logs and errors.
    pub fn kind(&self) -> &'static str {
        match self {
            Message::Hello(_) => "Hello",
            Message::Welcome(_) => "Welcome",
            Message::SceneSnapshot(_) => "SceneSnapshot",
            Message::FrameState(_) => "FrameState",
            Message::Ready(_) => "Ready",
            Message::Swap(_) => "Swap",
            Message::NodeStats(_) => "NodeStats",
            Message::ClockProbe(_) => "ClockProbe",
            Message::ClockReply(_) => "ClockReply",
            Message::Illumination(_) => "Illumination",
            Message::IlluminationResync(_) => "IlluminationResync",
            Message::ShowPattern(_) => "ShowPattern",
            Message::PatternShown(_) => "PatternShown",
            Message::CaptureFrames(_) => "CaptureFrames",
            Message::FrameChunk(_) => "FrameChunk",
            Message::CaptureFailed(_) => "CaptureFailed",
            Message::Bye(_) => "Bye",
            Message::IlluminationReady(_) => "IlluminationReady",
        }
    }
}
