//! Maps tracked bodies onto the scene: each configured body drives an
//! observer's head, a light or an object. Room coordinates are converted
//! to showcase world coordinates, every sample goes through a
//! [`PoseFilter`] (which bounds it to the tracking volume), and a frame's
//! state is filled from the filtered poses, so everything written into a
//! frame is finite. Time is an input (master-clock seconds), so this is
//! deterministic.

use super::dtrack::{DtrackError, parse_datagram};
use super::filter::{FilterConfig, Offered, PoseFilter};
use crate::scene_file::SceneNames;
use glam::{DMat3, DQuat, DVec3, EulerRot};
use showcase_proto::config::TrackingConfig;
use showcase_proto::{FrameState, Light, ObjectTransform, Pose, Showcase};
use std::collections::BTreeMap;

/// What a body drives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    /// The head of `Showcase::observers[i]`.
    Observer(usize),
    /// The position of `Showcase::lights[i]`.
    Light(usize),
    /// The pose of `Showcase::objects[i]`.
    Object(usize),
}

/// What the body target `kind:name` (`observer:`, `light:` or `object:`)
/// drives in a scene with these names; the error says what is wrong.
pub fn resolve_target(target: &str, names: &SceneNames) -> Result<Target, String> {
    let (kind, name) = target
        .split_once(':')
        .ok_or_else(|| format!("target {target:?} has no kind"))?;
    let (list, make): (&[String], fn(usize) -> Target) = match kind {
        "observer" => (&names.observers, Target::Observer),
        "light" => (&names.lights, Target::Light),
        "object" => (&names.objects, Target::Object),
        _ => return Err(format!("unknown target kind {kind:?}")),
    };
    list.iter()
        .position(|n| n == name)
        .map(make)
        .ok_or_else(|| format!("the scene has no {kind} named {name:?}"))
}

/// A tracking configuration the tracker cannot use.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TrackerError {
    /// A mapping that names something the scene does not have.
    #[error("tracking body {id}: {problem}")]
    Body {
        /// The body id.
        id: u32,
        /// What is wrong.
        problem: String,
    },
    /// Limits that `ClusterConfig::parse` would have refused.
    #[error("{field}: {problem}")]
    Limits {
        /// The field.
        field: String,
        /// What is wrong.
        problem: String,
    },
}

/// What one datagram did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IngestReport {
    /// Samples accepted (continuing a track or acquiring a body).
    pub accepted: usize,
    /// Samples of bodies being (re-)acquired, not used yet.
    pub acquiring: usize,
    /// Samples rejected by the filter, with the reason.
    pub rejected: Vec<(u32, String)>,
    /// Mapped bodies that were not tracked in this datagram.
    pub untracked: usize,
}

/// Tracking state of a running show.
#[derive(Debug)]
pub struct Tracker {
    room_rotation: DMat3,
    room_translation: DVec3,
    bodies: BTreeMap<u32, (Target, PoseFilter)>,
    last_sample_s: Option<f64>,
}

impl Tracker {
    /// Resolve the configured body mapping against the scene.
    pub fn new(config: &TrackingConfig, scene: &Showcase) -> Result<Self, TrackerError> {
        if let Some((field, problem)) = config.limits.problem() {
            return Err(TrackerError::Limits {
                field: field.into(),
                problem,
            });
        }
        let filter = FilterConfig::new(&config.limits, config.predict_ms / 1000.0);
        let mut bodies = BTreeMap::new();
        let names = SceneNames::of(scene);
        for b in &config.bodies {
            let target = resolve_target(&b.target, &names)
                .map_err(|problem| TrackerError::Body { id: b.id, problem })?;
            bodies.insert(b.id, (target, PoseFilter::new(filter.clone())));
        }
        let [rx, ry, rz] = config.room_rotation_deg.map(f64::to_radians);
        Ok(Self {
            room_rotation: DMat3::from_euler(EulerRot::XYZ, rx, ry, rz),
            room_translation: DVec3::from(config.room_translation),
            bodies,
            last_sample_s: None,
        })
    }

    /// Feed one DTrack datagram received at `now_s`.
    pub fn ingest(&mut self, now_s: f64, datagram: &str) -> Result<IngestReport, DtrackError> {
        let frame = parse_datagram(datagram)?;
        let mut report = IngestReport::default();
        for body in &frame.bodies {
            let Some((_, filter)) = self.bodies.get_mut(&body.id) else {
                continue;
            };
            if !body.is_tracked() {
                report.untracked += 1;
                continue;
            }
            let position = self.room_rotation * body.position + self.room_translation;
            let rotation = DQuat::from_mat3(&(self.room_rotation * body.rotation));
            match filter.offer(now_s, position, rotation) {
                Ok(Offered::Accepted | Offered::Acquired) => {
                    report.accepted += 1;
                    self.last_sample_s = Some(now_s);
                }
                Ok(Offered::Candidate { .. }) => report.acquiring += 1,
                Err(e) => report.rejected.push((body.id, e.to_string())),
            }
        }
        Ok(report)
    }

    /// Master-clock time of the newest accepted sample.
    pub fn last_sample_s(&self) -> Option<f64> {
        self.last_sample_s
    }

    /// Write the filtered poses at `now_s` into a frame: heads, light
    /// positions and object transforms. Bodies never seen leave the
    /// snapshot's values in place.
    pub fn apply(&self, now_s: f64, scene: &Showcase, frame: &mut FrameState) {
        for (target, filter) in self.bodies.values() {
            let Some((p, q)) = filter.pose(now_s) else {
                continue;
            };
            let (position, orientation) = (p.as_vec3(), q.as_quat().normalize());
            match *target {
                Target::Observer(i) => {
                    if let Some(h) = frame.heads.get_mut(i) {
                        *h = Pose {
                            position,
                            orientation,
                        };
                    }
                }
                Target::Light(i) => {
                    let name = &scene.lights[i].name;
                    if let Some(l) = frame.lights.iter_mut().find(|l| &l.name == name) {
                        move_light(&mut l.light, position);
                    }
                }
                Target::Object(i) => {
                    let base = scene.objects[i].transform;
                    let t = showcase_proto::Transform {
                        translation: position,
                        rotation: orientation,
                        scale: base.scale,
                    };
                    match frame
                        .object_transforms
                        .iter_mut()
                        .find(|o| o.object as usize == i)
                    {
                        Some(o) => o.transform = t,
                        None => frame.object_transforms.push(ObjectTransform {
                            object: i as u32,
                            transform: t,
                        }),
                    }
                }
            }
        }
    }
}

fn move_light(light: &mut Light, to: glam::Vec3) {
    let centre = light.position();
    match light {
        Light::Point { position, .. } | Light::Spot { position, .. } => *position = to,
        Light::Area { corner, .. } => *corner += to - centre,
    }
}

/// The frame state of a scene with nothing tracked yet: the snapshot's
/// heads and lights.
pub fn initial_frame(scene: &Showcase, frame: u64, time_s: f64, version: u64) -> FrameState {
    FrameState {
        frame,
        time_s,
        scene_version: version,
        heads: scene.observers.iter().map(|o| o.head).collect(),
        lights: scene.lights.clone(),
        object_transforms: Vec::new(),
        tracking_time_ns: None,
        illumination_version: None,
    }
}

/// The unit tests' scene: observers "alice" and "bob" and a point light
/// "key" at (0, 1, 0).
#[cfg(test)]
pub(crate) fn two_observers_and_a_light() -> Showcase {
    use showcase_proto::{LightSource, Observer};
    Showcase {
        observers: ["alice", "bob"]
            .map(|n| Observer {
                name: n.into(),
                head: Pose::default(),
                ipd: Observer::DEFAULT_IPD,
            })
            .to_vec(),
        lights: vec![LightSource {
            name: "key".into(),
            light: Light::Point {
                position: glam::Vec3::Y,
                intensity: glam::Vec3::ONE,
            },
        }],
        ..Showcase::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracking::scripted::{look_rotation, walk_datagram, walk_positions};
    use glam::Vec3;
    use showcase_proto::config::{BodyMapping, TrackingSource};

    fn scene() -> Showcase {
        two_observers_and_a_light()
    }

    fn config(bodies: &[(u32, &str)]) -> TrackingConfig {
        TrackingConfig {
            source: TrackingSource::Scripted,
            port: None,
            file: None,
            room_translation: [0.0; 3],
            room_rotation_deg: [0.0; 3],
            predict_ms: 0.0,
            limits: Default::default(),
            bodies: bodies
                .iter()
                .map(|(id, t)| BodyMapping {
                    id: *id,
                    target: (*t).into(),
                })
                .collect(),
        }
    }

    #[test]
    fn bodies_drive_heads_and_lights() {
        let s = scene();
        let cfg = config(&[(0, "observer:alice"), (1, "observer:bob"), (2, "light:key")]);
        let mut tr = Tracker::new(&cfg, &s).unwrap();
        let mut frame = initial_frame(&s, 0, 0.0, 1);
        for i in 0..120u64 {
            let t = i as f64 / 60.0;
            let r = tr.ingest(t, &walk_datagram(i, t)).unwrap();
            // Each body is acquired from three consistent samples.
            let acquiring = if i < 2 { 3 } else { 0 };
            assert_eq!(
                (r.accepted, r.acquiring),
                (3 - acquiring, acquiring),
                "{r:?}"
            );
        }
        tr.apply(2.0, &s, &mut frame);
        let t: f64 = 119.0 / 60.0;
        let expect = walk_positions(t)[0].as_vec3();
        let h = frame.heads[0];
        assert!((h.position.x - expect.x).abs() < 1e-5 && (h.position.z - expect.z).abs() < 1e-5);
        // The head looks along its local -z at the cabinet.
        let look = h.orientation * Vec3::NEG_Z;
        let to_centre = (Vec3::new(0.0, 0.15, 0.0) - h.position).normalize();
        assert!(look.dot(to_centre) > 0.9999, "{look} vs {to_centre}");
        let Light::Point { position, .. } = frame.lights[0].light else {
            panic!("light changed type");
        };
        assert!((position.y - 0.5).abs() < 1e-6);
        assert_eq!(tr.last_sample_s(), Some(t));
    }

    #[test]
    fn untracked_bodies_hold_and_jumps_are_rejected() {
        let s = scene();
        let mut tr = Tracker::new(&config(&[(1, "observer:bob")]), &s).unwrap();
        // Bob is untracked between 9.5 s and 10 s of the walk.
        for t in [9.47, 9.48, 9.49] {
            tr.ingest(t, &walk_datagram(0, t)).unwrap();
        }
        let r = tr.ingest(9.6, &walk_datagram(1, 9.6)).unwrap();
        assert_eq!((r.accepted, r.untracked), (0, 1));
        let mut f = initial_frame(&s, 0, 0.0, 1);
        tr.apply(9.6, &s, &mut f);
        let held = f.heads[1].position;
        let expect = walk_positions(9.49)[1];
        assert!((held.x as f64 - expect.x).abs() < 1e-5, "{held}");
        // A teleport by 2 m in 10 ms is rejected; the pose stays.
        let far = DVec3::new(3.0, 0.4, 0.0);
        let rot = look_rotation(far, DVec3::ZERO).to_cols_array();
        let dg = format!(
            "fr 9\n6d 1 [1 1.0][3000 400 0 0 0 0][{}]\n",
            rot.iter()
                .map(|v| format!("{v}"))
                .collect::<Vec<_>>()
                .join(" ")
        );
        let r = tr.ingest(9.61, &dg).unwrap();
        assert_eq!(r.rejected.len(), 1, "{r:?}");
        assert!(r.rejected[0].1.starts_with("jump of"), "{r:?}");
        tr.apply(9.61, &s, &mut f);
        assert_eq!(f.heads[1].position, held);
    }

    /// The red team's poison: a first sample 1e43 mm away used to be
    /// accepted, became inf as an f32, and every good sample after it was
    /// rejected as a jump. Now it never reaches a frame and the walk does.
    #[test]
    fn a_wild_first_sample_never_reaches_a_frame() {
        let s = scene();
        let mut tr = Tracker::new(&config(&[(0, "observer:alice")]), &s).unwrap();
        let r = tr
            .ingest(
                0.0,
                "fr 0\n6d 1 [0 1.000][1e43 0 0 0 0 0][1 0 0 0 1 0 0 0 1]\n",
            )
            .unwrap();
        assert_eq!((r.accepted, r.rejected.len()), (0, 1), "{r:?}");
        assert!(
            r.rejected[0]
                .1
                .starts_with("position (1.000e40, 0.000, 0.000) m is outside"),
            "{r:?}"
        );
        let mut f = initial_frame(&s, 0, 0.0, 1);
        tr.apply(0.0, &s, &mut f);
        assert_eq!(f.heads[0], Pose::default());
        for i in 1..=10u64 {
            let t = i as f64 / 60.0;
            tr.ingest(t, &walk_datagram(i, t)).unwrap();
        }
        tr.apply(10.0 / 60.0, &s, &mut f);
        let expect = walk_positions(10.0 / 60.0)[0].as_vec3();
        assert!(
            f.heads[0].position.distance(expect) < 1e-5,
            "{:?}",
            f.heads[0]
        );
    }

    #[test]
    fn limits_are_checked_when_not_parsed_from_a_file() {
        let mut cfg = config(&[(0, "observer:alice")]);
        cfg.limits.volume_max[0] = 1e43;
        let e = Tracker::new(&cfg, &scene()).unwrap_err().to_string();
        assert_eq!(
            e,
            "tracking.limits.volume_max: 1e43 is not a coordinate within 1000 m of the showcase"
        );
    }

    #[test]
    fn mappings_must_name_scene_things() {
        let s = scene();
        let e = Tracker::new(&config(&[(4, "observer:carol")]), &s).unwrap_err();
        assert_eq!(
            e.to_string(),
            "tracking body 4: the scene has no observer named \"carol\""
        );
        let e = Tracker::new(&config(&[(4, "lamp:key")]), &s).unwrap_err();
        assert!(e.to_string().contains("unknown target kind \"lamp\""));
    }
}
