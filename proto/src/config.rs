//! The cluster configuration shared by the master and every node: where
//! the master listens, which node drives which output on which PC, where
//! the certificates and calibrations are, and how tracking bodies map onto
//! observers, lights and objects. Parsing and checks are pure; reading the
//! file and checking that referenced files exist is the caller's job.

use crate::message::Role;
use serde::{Deserialize, Serialize};
use std::collections::{HashMap, HashSet};
use std::net::{IpAddr, Ipv6Addr};
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
    /// QUIC listen address (UDP), `HOST:PORT` or `IP:PORT`. Nodes connect
    /// here.
    pub listen: HostPort,
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
    /// Local UDP address to bind, `HOST:PORT` or `IP:PORT` (default: any
    /// port).
    pub bind: Option<HostPort>,
    /// The display output the node's window fills (`showcase-node
    /// --window`): the monitor's name as the display server gives it
    /// (`DP-1`, `HDMI-A-0`; `showcase-node --list-monitors` prints them) or
    /// its index in that list. Default: the primary monitor. Two outputs
    /// on one PC name two monitors.
    #[serde(default)]
    pub monitor: Option<String>,
}

/// An address as the configuration writes it: `HOST:PORT`, where HOST is
/// a DNS-style host name (`pc-0`, `localhost`), an IPv4 address or a
/// bracketed IPv6 address (`[::1]:4433`). Only the syntax is checked here;
/// the master and the nodes resolve the name where they use it.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Deserialize, Serialize)]
#[serde(try_from = "String", into = "String")]
pub struct HostPort {
    /// The host name or IP address, without brackets.
    pub host: String,
    /// The UDP port.
    pub port: u16,
}

impl HostPort {
    /// The host as an IP address, when it is one (no lookup needed).
    pub fn ip(&self) -> Option<IpAddr> {
        self.host.parse().ok()
    }
}

impl std::str::FromStr for HostPort {
    type Err = String;

    /// Parse `HOST:PORT`; the error says what is wrong and shows the form.
    fn from_str(s: &str) -> Result<Self, String> {
        let bad = |why: &str| {
            format!(
                "{s:?} is not HOST:PORT ({why}); write e.g. \"pc-0:4433\", \"192.168.10.10:4433\" or \"[::1]:4433\""
            )
        };
        let (host, port) = s.rsplit_once(':').ok_or_else(|| bad("no :PORT"))?;
        let port: u16 = port
            .parse()
            .map_err(|_| bad(&format!("port {port:?} is not a number in 0..=65535")))?;
        let host = if let Some(v6) = host.strip_prefix('[').and_then(|h| h.strip_suffix(']')) {
            v6.parse::<Ipv6Addr>()
                .map_err(|_| bad(&format!("{v6:?} is not an IPv6 address")))?;
            v6
        } else if host.contains(':') {
            return Err(bad("an IPv6 address needs brackets"));
        } else if host.parse::<std::net::Ipv4Addr>().is_ok() || is_host_name(host) {
            host
        } else {
            return Err(bad(&format!(
                "{host:?} is neither an IPv4 address nor a host name (letters, digits, '-' and '.')"
            )));
        };
        Ok(Self {
            host: host.to_owned(),
            port,
        })
    }
}

/// A DNS-style host name: dot-separated labels of 1 to 63 letters, digits
/// and hyphens, not starting or ending with a hyphen; 253 characters at most.
fn is_host_name(s: &str) -> bool {
    !s.is_empty()
        && s.len() <= 253
        && s.split('.').all(|l| {
            !l.is_empty()
                && l.len() <= 63
                && l.chars().all(|c| c.is_ascii_alphanumeric() || c == '-')
                && !l.starts_with('-')
                && !l.ends_with('-')
        })
}

impl TryFrom<String> for HostPort {
    type Error = String;
    fn try_from(s: String) -> Result<Self, String> {
        s.parse()
    }
}

impl From<HostPort> for String {
    fn from(a: HostPort) -> String {
        a.to_string()
    }
}

impl std::fmt::Display for HostPort {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.host.contains(':') {
            write!(f, "[{}]:{}", self.host, self.port)
        } else {
            write!(f, "{}:{}", self.host, self.port)
        }
    }
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
    /// Parse and check a configuration; `file` names it in errors. Fails
    /// with the first problem; [`ClusterConfig::problems`] lists them all.
    pub fn parse(text: &str, file: &str) -> Result<Self, ConfigError> {
        let cfg = Self::from_toml(text, file)?;
        match cfg.problems(file).into_iter().next() {
            Some(first) => Err(first),
            None => Ok(cfg),
        }
    }

    /// Parse a configuration without checking it (TOML syntax, keys and
    /// types only); `file` names it in errors.
    pub fn from_toml(text: &str, file: &str) -> Result<Self, ConfigError> {
        toml::from_str(text).map_err(|e| ConfigError::Parse {
            file: file.to_owned(),
            message: e.to_string().trim_end().to_owned(),
        })
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

    /// Every problem of a parsed configuration, in file order (empty: it
    /// can work); `file` names it in the errors.
    pub fn problems(&self, file: &str) -> Vec<ConfigError> {
        let mut out = Vec::new();
        let invalid = |field: &str, problem: String| ConfigError::Invalid {
            file: file.to_owned(),
            field: field.to_owned(),
            problem,
        };
        let m = &self.master;
        if !(m.target_hz.is_finite() && m.target_hz > 0.0 && m.target_hz <= 1000.0) {
            out.push(invalid(
                "master.target_hz",
                format!("{} is outside (0, 1000]", m.target_hz),
            ));
        }
        if !(m.deadline_ms.is_finite() && m.deadline_ms > 0.0) {
            out.push(invalid(
                "master.deadline_ms",
                format!("{} must be positive", m.deadline_ms),
            ));
        }
        let mut names = HashSet::new();
        let mut outputs: HashMap<(Role, &str), &str> = HashMap::new();
        let mut ports: HashMap<(&str, u16), String> = HashMap::new();
        let mut monitors: HashMap<(&str, &str), &str> = HashMap::new();
        ports.insert((m.host.as_str(), m.listen.port), "the master".into());
        for n in &self.nodes {
            if let Some(monitor) = n.monitor.as_deref()
                && let Some(first) = monitors.insert((n.host.as_str(), monitor), n.name.as_str())
            {
                out.push(invalid(
                    &format!("node {:?}.monitor", n.name),
                    format!(
                        "monitor {monitor:?} of {:?} is already node {first:?}'s: two outputs on one PC need two monitors",
                        n.host
                    ),
                ));
            }
            if !names.insert(n.name.as_str()) {
                out.push(ConfigError::DuplicateName {
                    file: file.to_owned(),
                    name: n.name.clone(),
                });
            }
            if let Some(first) = outputs.insert((n.role, n.output.as_str()), n.name.as_str()) {
                out.push(ConfigError::DuplicateRole {
                    file: file.to_owned(),
                    first: first.to_owned(),
                    second: n.name.clone(),
                    role: n.role,
                    output: n.output.clone(),
                });
            }
            if matches!(n.role, Role::Projector | Role::Camera) && n.calibration.is_none() {
                out.push(ConfigError::MissingCalibration {
                    file: file.to_owned(),
                    node: n.name.clone(),
                    role: n.role,
                });
            }
            if let Some(bind) = n.bind.as_ref().filter(|b| b.port != 0) {
                out.extend(
                    claim(
                        &mut ports,
                        file,
                        &n.host,
                        bind.port,
                        format!("node {:?}", n.name),
                    )
                    .err(),
                );
            }
        }
        if let Some(t) = &self.tracking {
            match t.source {
                TrackingSource::Dtrack => match t.port {
                    None => out.push(invalid("tracking.port", "dtrack needs a UDP port".into())),
                    Some(port) => out.extend(
                        claim(&mut ports, file, &m.host, port, "DTrack tracking".into()).err(),
                    ),
                },
                TrackingSource::Recording if t.file.is_none() => {
                    out.push(invalid(
                        "tracking.file",
                        "a recording source needs a file".into(),
                    ));
                }
                _ => {}
            }
            if !t.predict_ms.is_finite() || !(0.0..=200.0).contains(&t.predict_ms) {
                out.push(invalid(
                    "tracking.predict_ms",
                    format!("{} is outside 0..=200", t.predict_ms),
                ));
            }
            if let Some(v) = t
                .room_translation
                .iter()
                .chain(&t.room_rotation_deg)
                .find(|v| !v.is_finite())
            {
                out.push(invalid(
                    "tracking.room_*",
                    format!("value {v} is not finite"),
                ));
            }
            if let Some((field, problem)) = t.limits.problem() {
                out.push(invalid(field, problem));
            }
            let mut ids = HashSet::new();
            for b in &t.bodies {
                if !ids.insert(b.id) {
                    out.push(invalid(
                        "tracking.body",
                        format!("body id {} is mapped twice", b.id),
                    ));
                }
                let ok = ["observer:", "light:", "object:"]
                    .iter()
                    .any(|p| b.target.strip_prefix(p).is_some_and(|s| !s.is_empty()));
                if !ok {
                    out.push(invalid(
                        "tracking.body.target",
                        format!(
                            "{:?} is not observer:<name>, light:<name> or object:<name>",
                            b.target
                        ),
                    ));
                }
            }
        }
        out
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
    fn addresses_take_host_names_ips_and_bracketed_ipv6() {
        let hp = |s: &str| s.parse::<HostPort>();
        let a = hp("localhost:4433").unwrap();
        assert_eq!((a.host.as_str(), a.port, a.ip()), ("localhost", 4433, None));
        let a = hp("192.168.10.10:4433").unwrap();
        assert_eq!(a.ip(), Some("192.168.10.10".parse().unwrap()));
        assert_eq!(a.to_string(), "192.168.10.10:4433");
        let a = hp("[::1]:0").unwrap();
        assert_eq!((a.host.as_str(), a.port), ("::1", 0));
        assert_eq!(a.to_string(), "[::1]:0");
        assert_eq!(hp("pc-0.cabinet.lan:1").unwrap().host, "pc-0.cabinet.lan");
        for (bad, why) in [
            ("pc-0", "no :PORT"),
            ("pc-0:70000", "port \"70000\" is not a number"),
            ("pc-0:", "port \"\" is not a number"),
            (":4433", "\"\" is neither an IPv4 address nor a host name"),
            ("::1:4433", "an IPv6 address needs brackets"),
            ("[pc-0]:4433", "\"pc-0\" is not an IPv6 address"),
            ("pc_0:4433", "is neither"),
            ("-pc:4433", "is neither"),
            ("a..b:4433", "is neither"),
        ] {
            let err = hp(bad).unwrap_err();
            assert!(
                err.starts_with(&format!("{bad:?} is not HOST:PORT")),
                "{err}"
            );
            assert!(err.contains(why), "{bad}: {err:?} lacks {why:?}");
            assert!(err.contains("\"pc-0:4433\""), "shows the form: {err}");
        }
    }

    #[test]
    fn listen_and_bind_accept_host_names() {
        let c = ClusterConfig::parse(
            &LOOPBACK
                .replace("\"127.0.0.1:4433\"", "\"localhost:4433\"")
                .replace(
                    "output = \"face-1\"",
                    "output = \"face-1\"\nbind = \"pc-2:4500\"",
                ),
            "loopback.toml",
        )
        .unwrap();
        assert_eq!(c.master.listen.to_string(), "localhost:4433");
        let bind = c.node("face-1", "loopback.toml").unwrap().bind.as_ref();
        assert_eq!(bind.unwrap().to_string(), "pc-2:4500");
        check(
            |s| s.replace("\"127.0.0.1:4433\"", "\"local host:4433\""),
            "\"local host:4433\" is not HOST:PORT",
        );
        // The master's port still claims its port on its host.
        check(
            |s| s.replace("\"127.0.0.1:4433\"", "\"localhost:5000\""),
            "port 5000 on host \"localhost\" is used by both the master and DTrack tracking",
        );
    }

    #[test]
    fn two_outputs_on_one_pc_need_two_monitors() {
        let c = ClusterConfig::parse(CABINET, "cluster.toml").unwrap();
        let monitors = |host: &str| -> Vec<Option<&str>> {
            c.nodes
                .iter()
                .filter(|n| n.host == host)
                .map(|n| n.monitor.as_deref())
                .collect()
        };
        assert_eq!(monitors("pc-1"), [Some("DP-1"), Some("DP-2")]);
        // The same monitor twice on one PC is refused, naming both nodes.
        let text = CABINET.replacen("monitor = \"DP-2\"", "monitor = \"DP-1\"", 1);
        let problems: Vec<String> = ClusterConfig::from_toml(&text, "cluster.toml")
            .unwrap()
            .problems("cluster.toml")
            .iter()
            .map(ToString::to_string)
            .collect();
        assert_eq!(
            problems,
            [
                "cluster.toml: node \"projector-0\".monitor: monitor \"DP-1\" of \"pc-1\" is \
              already node \"face-0\"'s: two outputs on one PC need two monitors"
            ]
        );
        // The same name on another PC is another monitor.
        assert_eq!(monitors("pc-2"), [Some("DP-1"), Some("DP-2")]);
    }

    #[test]
    fn problems_lists_every_problem_in_file_order() {
        let text = LOOPBACK
            .replace("target_hz = 60", "target_hz = 0")
            .replace("name = \"face-1\"", "name = \"face-0\"")
            .replacen("calibration = \"scene\"\n", "", 1)
            .replace("{ id = 1, target", "{ id = 0, target");
        let c = ClusterConfig::from_toml(&text, "loopback.toml").unwrap();
        let problems: Vec<String> = c
            .problems("loopback.toml")
            .iter()
            .map(ToString::to_string)
            .collect();
        assert_eq!(
            problems,
            [
                "loopback.toml: master.target_hz: 0 is outside (0, 1000]",
                "loopback.toml: node name \"face-0\" is used twice",
                "loopback.toml: node \"projector-0\" (projector) has no calibration; give a calibration file or \"scene\"",
                "loopback.toml: tracking.body: body id 0 is mapped twice",
            ]
        );
        // parse fails with the first of them.
        assert_eq!(
            ClusterConfig::parse(&text, "loopback.toml")
                .unwrap_err()
                .to_string(),
            problems[0]
        );
        let ok = ClusterConfig::from_toml(LOOPBACK, "loopback.toml").unwrap();
        assert!(ok.problems("loopback.toml").is_empty());
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
