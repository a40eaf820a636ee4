//! The built-in tracking session: two observers strolling in front of the
//! cabinet's two CRT sides, a light carried above it and a virtual object
//! slid to and fro, produced as DTrack datagrams so
//! that it travels the same path as live tracking (parser, filter,
//! recording, replay).

use glam::{DMat3, DVec3};
use showcase_proto::{ObjectKind, Showcase, Transform};
use std::f64::consts::TAU;

/// DTrack body id of the first observer's head; the second is id + 1.
pub const FIRST_HEAD_BODY: u32 = 0;
/// DTrack body id of the carried light.
pub const LIGHT_BODY: u32 = 2;
/// DTrack body id of the carried virtual object ([`carried_object`]).
pub const OBJECT_BODY: u32 = 3;
/// How far the walk carries the virtual object either side of its place
/// (metres): issue #23's object move is 5 cm.
pub const OBJECT_SWAY: f64 = 0.05;

/// A head at `position` looking at `target` (y up), as a DTrack rotation:
/// columns are the body's x (right), y (up) and z (back) axes, so the head
/// looks along its local -z.
pub fn look_rotation(position: DVec3, target: DVec3) -> DMat3 {
    let back = (position - target).normalize();
    let right = DVec3::Y.cross(back).normalize();
    let up = back.cross(right);
    DMat3::from_cols(right, up, back)
}

/// Format one `6d` body block (positions in mm, rotation column-wise).
fn body_block(id: u32, quality: f64, position: DVec3, rotation: DMat3) -> String {
    let p = position * 1000.0;
    let r = rotation.to_cols_array();
    format!(
        "[{id} {quality:.3}][{:.3} {:.3} {:.3} 0 0 0][{}]",
        p.x,
        p.y,
        p.z,
        r.iter()
            .map(|v| format!("{v:.6}"))
            .collect::<Vec<_>>()
            .join(" ")
    )
}

/// The virtual object the walk carries in `scene`: its first virtual
/// object that is not a mirror (a mirror's cube map is the costliest
/// thing to move, and the paper's moving objects are diffuse), if any.
pub fn carried_object(scene: &Showcase) -> Option<usize> {
    scene
        .objects
        .iter()
        .position(|o| o.kind == ObjectKind::Virtual && !o.material.reflective)
}

/// Where the walk holds an object whose scene transform is `base` at `t`
/// seconds: slid to and fro along x by up to [`OBJECT_SWAY`], once every
/// 12.6 s, keeping its rotation.
pub fn carried_pose(base: &Transform, t: f64) -> (DVec3, DMat3) {
    let position = base.translation.as_dvec3() + DVec3::X * OBJECT_SWAY * (0.5 * t).sin();
    (position, DMat3::from_quat(base.rotation.as_dquat()))
}

/// [`walk_datagram`], and where the scene has an object to carry
/// ([`carried_object`]; `base` its transform), the object's body
/// ([`OBJECT_BODY`]) at [`carried_pose`].
pub fn walk_datagram_carrying(frame: u64, t: f64, base: Option<&Transform>) -> String {
    let Some(base) = base else {
        return walk_datagram(frame, t);
    };
    let (position, rotation) = carried_pose(base, t);
    let mut blocks = walk_blocks(t);
    blocks.push(body_block(OBJECT_BODY, 1.0, position, rotation));
    datagram(frame, t, &blocks)
}

/// The datagram of frame `frame` at time `t` seconds of the walk: two
/// observers strolling to and fro around the cabinet, 1.0 and 1.2 m from
/// its centre, each in front of its own CRT side (the first in front of
/// the front side, +z, the second in front of the right side, +x, as in
/// `deploy/scenes/showcase.toml`), sweeping 0.4 rad either way with a
/// slight bob, looking at its centre, and a light circling 0.5 m above the
/// floor. The second observer steps out of the tracked volume
/// (quality -1) for half a second every 10 s, as happens in practice.
pub fn walk_datagram(frame: u64, t: f64) -> String {
    datagram(frame, t, &walk_blocks(t))
}

/// The heads' and the light's body blocks at `t`.
fn walk_blocks(t: f64) -> Vec<String> {
    let centre = DVec3::new(0.0, 0.15, 0.0);
    let [alice, bob, light] = walk_positions(t);
    let bob_tracked = (t % 10.0) < 9.5;
    vec![
        body_block(FIRST_HEAD_BODY, 1.0, alice, look_rotation(alice, centre)),
        body_block(
            FIRST_HEAD_BODY + 1,
            if bob_tracked { 1.0 } else { -1.0 },
            bob,
            look_rotation(bob, centre),
        ),
        body_block(LIGHT_BODY, 1.0, light, DMat3::IDENTITY),
    ]
}

fn datagram(frame: u64, t: f64, blocks: &[String]) -> String {
    let n = blocks.len();
    format!(
        "fr {frame}\r\nts {t:.6}\r\n6dcal {n}\r\n6d {n} {}\r\n",
        blocks.join("")
    )
}

/// Where the walk puts the first observer's head, the second's and the
/// light at `t` seconds (metres; see [`walk_datagram`]).
pub fn walk_positions(t: f64) -> [DVec3; 3] {
    let a = std::f64::consts::FRAC_PI_2 + 0.4 * (0.35 * t).sin();
    let alice = DVec3::new(
        1.0 * a.cos(),
        0.45 + 0.02 * (TAU * 0.9 * t).sin(),
        1.0 * a.sin(),
    );
    let b = 0.4 * (0.3 * t + 0.5).sin();
    let bob = DVec3::new(
        1.2 * b.cos(),
        0.40 + 0.02 * (TAU * 1.1 * t).sin(),
        1.2 * b.sin(),
    );
    let l = 0.6 * t;
    let light = DVec3::new(0.25 * l.cos(), 0.5, 0.25 * l.sin());
    [alice, bob, light]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracking::parse_datagram;

    #[test]
    fn walk_parses_and_heads_look_at_the_cabinet() {
        for (i, t) in [0.0, 1.7, 9.7, 33.3].into_iter().enumerate() {
            let f = parse_datagram(&walk_datagram(i as u64, t)).unwrap();
            assert_eq!(f.bodies.len(), 3);
            assert_eq!(f.frame, Some(i as u64));
            for b in &f.bodies[..2] {
                if !b.is_tracked() {
                    continue;
                }
                // The head's -z axis points at the cabinet centre.
                let forward = -b.rotation.z_axis;
                let to_centre = (DVec3::new(0.0, 0.15, 0.0) - b.position).normalize();
                assert!(forward.dot(to_centre) > 0.9999, "{forward} vs {to_centre}");
                let r = (b.position.x.powi(2) + b.position.z.powi(2)).sqrt();
                assert!((0.99..1.21).contains(&r), "radius {r}");
            }
            // Each stays in front of its own side: the first on +z, the
            // second on +x, within 0.4 rad of the side's axis.
            let angle = |b: &crate::tracking::dtrack::Body6d| b.position.z.atan2(b.position.x);
            assert!((angle(&f.bodies[0]) - std::f64::consts::FRAC_PI_2).abs() <= 0.4 + 1e-9);
            if f.bodies[1].is_tracked() {
                assert!(angle(&f.bodies[1]).abs() <= 0.4 + 1e-9);
            }
        }
        assert!(!parse_datagram(&walk_datagram(0, 9.7)).unwrap().bodies[1].is_tracked());
    }

    #[test]
    fn the_carried_object_slides_within_its_sway_and_keeps_its_rotation() {
        let base = Transform {
            translation: glam::Vec3::new(0.1, 0.0, -0.1),
            rotation: glam::Quat::from_rotation_y(-0.5),
            scale: glam::Vec3::splat(0.3),
        };
        let mut reach = 0.0f64;
        for i in 0..800u64 {
            let t = i as f64 / 60.0;
            let f = parse_datagram(&walk_datagram_carrying(i, t, Some(&base))).unwrap();
            assert_eq!(f.bodies.len(), 4);
            let b = &f.bodies[3];
            assert_eq!(b.id, OBJECT_BODY);
            let offset = b.position - base.translation.as_dvec3();
            assert!(offset.y.abs() < 1e-6 && offset.z.abs() < 1e-6, "{offset}");
            assert!(offset.x.abs() <= OBJECT_SWAY + 1e-6, "{offset}");
            reach = reach.max(offset.x.abs());
            let q = glam::DQuat::from_mat3(&b.rotation);
            assert!(q.angle_between(base.rotation.as_dquat()) < 1e-5);
            // The other bodies are the plain walk's.
            assert_eq!(
                &f.bodies[..3],
                &parse_datagram(&walk_datagram(i, t)).unwrap().bodies[..]
            );
        }
        assert!(
            reach > 0.99 * OBJECT_SWAY,
            "the walk carried it {reach} m at most"
        );
        assert_eq!(walk_datagram_carrying(5, 0.1, None), walk_datagram(5, 0.1));
    }
}
