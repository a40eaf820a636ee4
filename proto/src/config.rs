//! The cluster configuration shared by the master and every node: where
//! the master listens, which node drives which output on which PC, where
//! the certificates and calibrations are, and how tracking bodies map onto
//! observers, lights and objects. Parsing and checks are pure; reading the
//! file and checking that referenced files exist is the caller's job.

use crate::message::Role;
use serde::{Deserialize, Serialize};
use std::collections::{HashMap, HashSet};
use std::net::SocketAddr;
use std::path::PathBuf;

/// A cluster configuration file (TOML). See `deploy/cluster.toml`.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClusterConfig {
    /// The master.
    pub master: MasterConfig,
    /// Tracking input (optional: a cluster can run on scripted heads).
    pub tracking: Option<TrackingConfig>,
    /// The render nodes.
    #[serde(rename = "node", default)]
    pub nodes: Vec<NodeConfig>,
}

/// The master's settings.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MasterConfig {
    /// Name of the PC the master runs on.
    pub host: String,
    /// QUIC listen address (UDP). Nodes connect here.
    pub listen: SocketAddr,
    /// Scene file, relative to the configuration file.
    pub scene: PathBuf,
    /// Folder with `ca.pem` and the peers' certificates and keys.
    pub certs: PathBuf,
    /// Target frame rate.
    #[serde(default = "default_hz")]
    pub target_hz: f32,
    /// Swap-barrier deadline in milliseconds.
    #[serde(default = "default_deadline")]
    pub deadline_ms: f32,
}

fn default_hz() -> f32 {
    60.0
}
fn default_deadline() -> f32 {
    50.0
}

/// Where tracking data comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum TrackingSource {
    /// A.R.T. DTrack ASCII datagrams on `port`.
    Dtrack,
    /// A recorded session `file`.
    Recording,
    /// The scripted walk built into the master.
    Scripted,
}

/// Tracking settings.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TrackingConfig {
    /// The source.
    pub source: TrackingSource,
    /// UDP port for DTrack (on the master's host).
    pub port: Option<u16>,
    /// Recorded session for `recording`.
    pub file: Option<PathBuf>,
    /// DTrack room to showcase world: translation in metres.
    #[serde(default)]
    pub room_translation: [f64; 3],
    /// DTrack room to showcase world: rotation, XYZ Euler degrees.
    #[serde(default)]
    pub room_rotation_deg: [f64; 3],
    /// Constant-velocity prediction in milliseconds (0: off).
    #[serde(default)]
    pub predict_ms: f64,
    /// Body id to target mapping.
    #[serde(rename = "body", default)]
    pub bodies: Vec<BodyMapping>,
    /// Where tracked bodies can be and how fast they can move
    /// (`[tracking.limits]`; every key has a default).
    #[serde(default)]
    pub limits: TrackingLimits,
}

/// Which tracked poses are physically possible. The volume is in showcase
/// world coordinates (metres, origin at the centre of the showcase floor,
/// y up), after the room transform: it stays put when DTrack is
/// recalibrated, and it bounds every pose that reaches a frame state, so
/// nothing overflows when poses become f32.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrackingLimits {
    /// Lowest corner of the tracking volume (metres, world coordinates).
    pub volume_min: [f64; 3],
    /// Highest corner of the tracking volume (metres, world coordinates).
    pub volume_max: [f64; 3],
    /// Fastest plausible linear speed (m/s); faster jumps are rejected.
    pub max_speed: f64,
    /// Fastest plausible angular speed (degrees/s).
    pub max_angular_speed_deg: f64,
    /// A body with no accepted sample for this long (milliseconds) is
    /// re-acquired from a short run of consistent samples instead of being
    /// held to its old pose.
    pub reacquire_ms: f64,
}

impl TrackingLimits {
    /// Largest coordinate a volume corner may have (metres): a room, not a
    /// country, and far inside f32's range.
    pub const MAX_COORDINATE: f64 = 1000.0;

    /// The first problem with these limits, as (field, problem), if any.
    pub fn problem(&self) -> Option<(&'static str, String)> {
        for (field, corner) in [
            ("tracking.limits.volume_min", self.volume_min),
            ("tracking.limits.volume_max", self.volume_max),
        ] {
            if let Some(v) = corner
                .iter()
                .find(|v| v.is_nan() || v.abs() > Self::MAX_COORDINATE)
            {
                return Some((
                    field,
                    format!(
                        "{} is not a coordinate within {} m of the showcase",
                        if v.abs() < 1e6 {
                            v.to_string()
                        } else {
                            format!("{v:e}")
                        },
                        Self::MAX_COORDINATE
                    ),
                ));
            }
        }
        for (axis, (lo, hi)) in ["x", "y", "z"]
            .iter()
            .zip(self.volume_min.iter().zip(&self.volume_max))
        {
            if lo >= hi {
                return Some((
                    "tracking.limits.volume_min",
                    format!(
                        "{axis} = {lo} is not below volume_max's {hi}; give the lowest corner in volume_min"
                    ),
                ));
            }
        }
        for (field, v, hi) in [
            ("tracking.limits.max_speed", self.max_speed, 1000.0),
            (
                "tracking.limits.max_angular_speed_deg",
                self.max_angular_speed_deg,
                100_000.0,
            ),
            ("tracking.limits.reacquire_ms", self.reacquire_ms, 60_000.0),
        ] {
            if !(v > 0.0 && v <= hi) {
                return Some((field, format!("{v} is outside (0, {hi}]")));
            }
        }
        None
    }
}

impl Default for TrackingLimits {
    fn default() -> Self {
        Self {
            // A few metres around the cabinet, from the room's floor (the
            // cabinet stands on a table) to well above a standing head.
            volume_min: [-4.0, -1.5, -4.0],
            volume_max: [4.0, 2.5, 4.0],
            // A walking head moves well under 3 m/s and turns under 720 deg/s.
            max_speed: 5.0,
            max_angular_speed_deg: 1000.0,
            reacquire_ms: 500.0,
        }
    }
}

/// A tracked body drives an observer's head, a light or an object.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BodyMapping {
    /// DTrack body id.
    pub id: u32,
    /// `observer:<name>`, `light:<name>` or `object:<name>`.
    pub target: String,
}

/// One render node.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NodeConfig {
    /// Node name; also its certificate name.
    pub name: String,
    /// What it drives.
    pub role: Role,
    /// Name of the PC it runs on.
    pub host: String,
    /// The scene's face, projector or camera it drives.
    pub output: String,
    /// Calibration JSON for projectors and cameras, relative to the
    /// configuration file, or `"scene"` to use the scene's own device.
    pub calibration: Option<String>,
    /// Local UDP address to bind (default: any port).
    pub bind: Option<SocketAddr>,
}

/// A configuration that cannot work; names the node or field.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ConfigError {
    /// TOML syntax, an unknown key or a wrong type.
    #[error("{file}: {message}")]
    Parse {
        /// The file.
        file: String,
        /// toml's message, with line and column.
        message: String,
    },
    /// A node name that is not in the configuration.
    #[error("{file}: unknown node {name:?}; the configuration has {known:?}")]
    UnknownNode {
        /// The file.
        file: String,
        /// The name asked for.
        name: String,
        /// The names it has.
        known: Vec<String>,
    },
    /// Two nodes share a name.
    #[error("{file}: node name {name:?} is used twice")]
    DuplicateName {
        /// The file.
        file: String,
        /// The name.
        name: String,
    },
    /// Two nodes drive the same output in the same role.
    #[error("{file}: nodes {first:?} and {second:?} both drive {role} {output:?}")]
    DuplicateRole {
        /// The file.
        file: String,
        /// First node.
        first: String,
        /// Second node.
        second: String,
        /// Their role.
        role: Role,
        /// The output.
        output: String,
    },
    /// A projector or camera node without a calibration.
    #[error(
        "{file}: node {node:?} ({role}) has no calibration; give a calibration file or \"scene\""
    )]
    MissingCalibration {
        /// The file.
        file: String,
        /// The node.
        node: String,
        /// Its role.
        role: Role,
    },
    /// Two services want the same UDP port on the same host.
    #[error("{file}: port {port} on host {host:?} is used by both {first} and {second}")]
    PortClash {
        /// The file.
        file: String,
        /// The host.
        host: String,
        /// The port.
        port: u16,
        /// First user.
        first: String,
        /// Second user.
        second: String,
    },
    /// Any other invalid value.
    #[error("{file}: {field}: {problem}")]
    Invalid {
        /// The file.
        file: String,
        /// The field.
        field: String,
        /// What is wrong.
        problem: String,
    },
}

impl ClusterConfig {
    /// Parse and check a configuration; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<Self, ConfigError> {
        let cfg: ClusterConfig = toml::from_str(text).map_err(|e| ConfigError::Parse {
            file: file.to_owned(),
            message: e.to_string().trim_end().to_owned(),
        })?;
        cfg.check(file)?;
        Ok(cfg)
    }

    /// The node called `name`.
    pub fn node(&self, name: &str, file: &str) -> Result<&NodeConfig, ConfigError> {
        self.nodes
            .iter()
            .find(|n| n.name == name)
            .ok_or_else(|| ConfigError::UnknownNode {
                file: file.to_owned(),
                name: name.to_owned(),
                known: self.nodes.iter().map(|n| n.name.clone()).collect(),
            })
    }

    fn check(&self, file: &str) -> Result<(), ConfigError> {
        let invalid = |field: &str, problem: String| ConfigError::Invalid {
            file: file.to_owned(),
            field: field.to_owned(),
            problem,
        };
        let m = &self.master;
        if !(m.target_hz.is_finite() && m.target_hz > 0.0 && m.target_hz <= 1000.0) {
            return Err(invalid(
                "master.target_hz",
                format!("{} is outside (0, 1000]", m.target_hz),
            ));
        }
        if !(m.deadline_ms.is_finite() && m.deadline_ms > 0.0) {
            return Err(invalid(
                "master.deadline_ms",
                format!("{} must be positive", m.deadline_ms),
            ));
        }
        let mut names = HashSet::new();
        let mut outputs: HashMap<(Role, &str), &str> = HashMap::new();
        let mut ports: HashMap<(&str, u16), String> = HashMap::new();
        ports.insert((m.host.as_str(), m.listen.port()), "the master".into());
        for n in &self.nodes {
            if !names.insert(n.name.as_str()) {
                return Err(ConfigError::DuplicateName {
                    file: file.to_owned(),
                    name: n.name.clone(),
                });
            }
            if let Some(first) = outputs.insert((n.role, n.output.as_str()), n.name.as_str()) {
                return Err(ConfigError::DuplicateRole {
                    file: file.to_owned(),
                    first: first.to_owned(),
                    second: n.name.clone(),
                    role: n.role,
                    output: n.output.clone(),
                });
            }
            if matches!(n.role, Role::Projector | Role::Camera) && n.calibration.is_none() {
                return Err(ConfigError::MissingCalibration {
                    file: file.to_owned(),
                    node: n.name.clone(),
                    role: n.role,
                });
            }
            if let Some(bind) = n.bind.filter(|b| b.port() != 0) {
                claim(
                    &mut ports,
                    file,
                    &n.host,
                    bind.port(),
                    format!("node {:?}", n.name),
                )?;
            }
        }
        if let Some(t) = &self.tracking {
            match t.source {
                TrackingSource::Dtrack => {
                    let port = t.port.ok_or_else(|| {
                        invalid("tracking.port", "dtrack needs a UDP port".into())
                    })?;
                    claim(&mut ports, file, &m.host, port, "DTrack tracking".into())?;
                }
                TrackingSource::Recording if t.file.is_none() => {
                    return Err(invalid(
                        "tracking.file",
                        "a recording source needs a file".into(),
                    ));
                }
                _ => {}
            }
            if !t.predict_ms.is_finite() || !(0.0..=200.0).contains(&t.predict_ms) {
                return Err(invalid(
                    "tracking.predict_ms",
                    format!("{} is outside 0..=200", t.predict_ms),
                ));
            }
            for v in t.room_translation.iter().chain(&t.room_rotation_deg) {
                if !v.is_finite() {
                    return Err(invalid(
                        "tracking.room_*",
                        format!("value {v} is not finite"),
                    ));
                }
            }
            if let Some((field, problem)) = t.limits.problem() {
                return Err(invalid(field, problem));
            }
            let mut ids = HashSet::new();
            for b in &t.bodies {
                if !ids.insert(b.id) {
                    return Err(invalid(
                        "tracking.body",
                        format!("body id {} is mapped twice", b.id),
                    ));
                }
                let ok = ["observer:", "light:", "object:"]
                    .iter()
                    .any(|p| b.target.strip_prefix(p).is_some_and(|s| !s.is_empty()));
                if !ok {
                    return Err(invalid(
                        "tracking.body.target",
                        format!(
                            "{:?} is not observer:<name>, light:<name> or object:<name>",
                            b.target
                        ),
                    ));
                }
            }
        }
        Ok(())
    }
}

fn claim<'a>(
    ports: &mut HashMap<(&'a str, u16), String>,
    file: &str,
    host: &'a str,
    port: u16,
    who: String,
) -> Result<(), ConfigError> {
    if let Some(first) = ports.get(&(host, port)) {
        return Err(ConfigError::PortClash {
            file: file.to_owned(),
            host: host.to_owned(),
            port,
            first: first.clone(),
            second: who,
        });
    }
    ports.insert((host, port), who);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const LOOPBACK: &str = include_str!("../../deploy/loopback.toml");
    const CABINET: &str = include_str!("../../deploy/cluster.toml");

    #[test]
    fn shipped_configs_parse() {
        let c = ClusterConfig::parse(LOOPBACK, "loopback.toml").unwrap();
        assert_eq!(c.nodes.len(), 4);
        let c = ClusterConfig::parse(CABINET, "cluster.toml").unwrap();
        assert_eq!(c.nodes.len(), 5);
        // The cabinet's file spells out the default limits.
        assert_eq!(
            c.tracking.as_ref().unwrap().limits,
            TrackingLimits::default()
        );
        let hosts: HashSet<_> = c.nodes.iter().map(|n| n.host.as_str()).collect();
        assert_eq!(hosts.len(), 3, "three PCs");
        assert_eq!(c.node("face-1", "cluster.toml").unwrap().role, Role::Face);
    }

    #[track_caller]
    fn check(edit: impl Fn(&str) -> String, expected: &str) {
        let err = ClusterConfig::parse(&edit(LOOPBACK), "loopback.toml").unwrap_err();
        let msg = err.to_string();
        assert!(msg.starts_with("loopback.toml: "), "{msg}");
        assert!(msg.contains(expected), "{msg:?} lacks {expected:?}");
    }

    #[test]
    fn bad_configs_get_clear_errors() {
        let c = ClusterConfig::parse(LOOPBACK, "loopback.toml").unwrap();
        let err = c
            .node("projector-9", "loopback.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("unknown node \"projector-9\""), "{err}");
        check(
            |s| s.replace("target_hz = 60", "target_hz = 60\ncolour = 1"),
            "unknown field `colour`",
        );
        check(
            |s| s.replace("name = \"face-1\"", "name = \"face-0\""),
            "node name \"face-0\" is used twice",
        );
        check(
            |s| s.replace("output = \"face-1\"", "output = \"face-0\""),
            "nodes \"face-0\" and \"face-1\" both drive face \"face-0\"",
        );
        check(
            |s| s.replacen("calibration = \"scene\"\n", "", 1),
            "(projector) has no calibration",
        );
        check(
            |s| s.replace("port = 5000", "port = 4433"),
            "port 4433 on host \"localhost\" is used by both the master and DTrack tracking",
        );
        check(
            |s| s.replace("target_hz = 60", "target_hz = nan"),
            "master.target_hz",
        );
        check(
            |s| s.replace("role = \"face\"", "role = \"wall\""),
            "unknown variant `wall`",
        );
        check(
            |s| s.replace("observer:observer-0", "observer-0"),
            "is not observer:<name>",
        );
    }

    #[test]
    fn tracking_limits_default_and_are_checked() {
        let c = ClusterConfig::parse(LOOPBACK, "loopback.toml").unwrap();
        assert_eq!(c.tracking.unwrap().limits, TrackingLimits::default());
        let limits = |keys: &'static str| {
            move |s: &str| {
                s.replacen(
                    "[[node]]",
                    &format!("[tracking.limits]\n{keys}\n[[node]]"),
                    1,
                )
            }
        };
        let c = ClusterConfig::parse(
            &limits("volume_min = [-1, 0, -1]\nvolume_max = [1, 2, 1]\nmax_speed = 3\nreacquire_ms = 250")(LOOPBACK),
            "loopback.toml",
        )
        .unwrap();
        let l = c.tracking.unwrap().limits;
        assert_eq!(
            (l.volume_min, l.volume_max),
            ([-1.0, 0.0, -1.0], [1.0, 2.0, 1.0])
        );
        assert_eq!((l.max_speed, l.reacquire_ms), (3.0, 250.0));
        assert_eq!(l.max_angular_speed_deg, 1000.0);
        check(
            limits("volume_max = [1, -2, 1]"),
            "tracking.limits.volume_min: y = -1.5 is not below volume_max's -2",
        );
        check(
            limits("volume_min = [-1e43, 0, 0]"),
            "tracking.limits.volume_min: -1e43 is not a coordinate within 1000 m of the showcase",
        );
        check(
            limits("volume_max = [nan, 1, 1]"),
            "tracking.limits.volume_max: NaN is not",
        );
        check(
            limits("max_speed = 0"),
            "tracking.limits.max_speed: 0 is outside (0, 1000]",
        );
        check(
            limits("max_angular_speed_deg = inf"),
            "max_angular_speed_deg: inf is outside",
        );
        check(
            limits("reacquire_ms = -1"),
            "tracking.limits.reacquire_ms: -1 is outside",
        );
        check(limits("volume = 3"), "unknown field `volume`");
    }
}
