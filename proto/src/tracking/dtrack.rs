//! A.R.T. DTrack ASCII output (DESIGN section 6a): one UDP datagram per
//! frame, lines `fr`, `ts`, `6dcal` and `6d`; other lines are ignored.
//! Positions are millimetres, rotation matrices are given column-wise, and
//! quality -1 means the body is not tracked.

use glam::{DMat3, DVec3};

/// One tracked rigid body of a `6d` line.
#[derive(Clone, Debug, PartialEq)]
pub struct Body6d {
    /// Body id as configured in DTrack (0-based).
    pub id: u32,
    /// Tracking quality in `[0, 1]`, or negative when not tracked.
    pub quality: f64,
    /// Position in metres (DTrack room coordinates).
    pub position: DVec3,
    /// Orientation (body to room).
    pub rotation: DMat3,
}

impl Body6d {
    /// True when DTrack tracked this body in this frame.
    pub fn is_tracked(&self) -> bool {
        self.quality >= 0.0
    }
}

/// One datagram.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DtrackFrame {
    /// Frame counter (`fr`).
    pub frame: Option<u64>,
    /// Timestamp in seconds since midnight (`ts`).
    pub timestamp: Option<f64>,
    /// Number of calibrated bodies (`6dcal`).
    pub calibrated: Option<u32>,
    /// The bodies of the `6d` line.
    pub bodies: Vec<Body6d>,
}

/// A datagram that could not be parsed; names the line and the problem.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("dtrack line {line} ({tag}): {problem}")]
pub struct DtrackError {
    /// 1-based line number within the datagram.
    pub line: usize,
    /// The line's tag (`fr`, `6d`, ...).
    pub tag: String,
    /// What is wrong.
    pub problem: String,
}

/// Parse one DTrack ASCII datagram.
pub fn parse_datagram(text: &str) -> Result<DtrackFrame, DtrackError> {
    let mut out = DtrackFrame::default();
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        let Some((tag, rest)) = line.split_once(char::is_whitespace).or(Some((line, ""))) else {
            continue;
        };
        let err = |problem: String| DtrackError {
            line: i + 1,
            tag: tag.to_owned(),
            problem,
        };
        let rest = rest.trim();
        match tag {
            "fr" => {
                out.frame = Some(
                    rest.parse()
                        .map_err(|_| err(format!("bad frame counter {rest:?}")))?,
                )
            }
            "ts" => {
                let ts: f64 = rest
                    .parse()
                    .map_err(|_| err(format!("bad timestamp {rest:?}")))?;
                if !ts.is_finite() {
                    return Err(err(format!("timestamp {ts} is not finite")));
                }
                out.timestamp = Some(ts);
            }
            "6dcal" => {
                out.calibrated = Some(
                    rest.parse()
                        .map_err(|_| err(format!("bad body count {rest:?}")))?,
                )
            }
            "6d" => out.bodies = parse_6d(rest).map_err(err)?,
            _ => {} // 3d, 6df, gl, 6dmt, ...: not ours.
        }
    }
    Ok(out)
}

fn parse_6d(rest: &str) -> Result<Vec<Body6d>, String> {
    let (count, blocks) = rest
        .split_once('[')
        .map_or((rest, ""), |(c, _)| (c, &rest[c.len()..]));
    let count: usize = count
        .trim()
        .parse()
        .map_err(|_| format!("bad body count {:?}", count.trim()))?;
    let groups = brackets(blocks)?;
    if groups.len() != 3 * count {
        return Err(format!(
            "{count} bodies announced but {} bracket groups found (expected {})",
            groups.len(),
            3 * count
        ));
    }
    groups
        .chunks(3)
        .enumerate()
        .map(|(b, g)| {
            let head = numbers(g[0], 2).map_err(|e| format!("body {b} [id quality]: {e}"))?;
            let pos =
                numbers(g[1], 6).map_err(|e| format!("body {b} [x y z eta theta phi]: {e}"))?;
            let rot = numbers(g[2], 9).map_err(|e| format!("body {b} [rotation]: {e}"))?;
            if head[0] < 0.0 || head[0].fract() != 0.0 || head[0] > u32::MAX as f64 {
                return Err(format!(
                    "body {b}: id {} is not a non-negative integer",
                    head[0]
                ));
            }
            // Column-wise: b0 b1 b2 is the first column.
            let rotation = DMat3::from_cols_slice(&rot);
            let quality = head[1];
            if quality >= 0.0 {
                let err = (rotation.transpose() * rotation - DMat3::IDENTITY)
                    .to_cols_array()
                    .iter()
                    .fold(0.0f64, |m, x| m.max(x.abs()));
                if err > 1e-3 || rotation.determinant() < 0.0 {
                    return Err(format!(
                        "body {b}: rotation is not a rotation (error {err:.1e})"
                    ));
                }
            }
            Ok(Body6d {
                id: head[0] as u32,
                quality,
                position: DVec3::new(pos[0], pos[1], pos[2]) / 1000.0,
                rotation,
            })
        })
        .collect()
}

/// The contents of each `[...]` group.
fn brackets(s: &str) -> Result<Vec<&str>, String> {
    let mut out = Vec::new();
    let mut rest = s.trim();
    while !rest.is_empty() {
        let Some(after) = rest.strip_prefix('[') else {
            return Err(format!(
                "expected '[' at {:?}",
                rest.chars().take(12).collect::<String>()
            ));
        };
        let Some(end) = after.find(']') else {
            return Err("unterminated '['".into());
        };
        out.push(&after[..end]);
        rest = after[end + 1..].trim_start();
    }
    Ok(out)
}

fn numbers(group: &str, n: usize) -> Result<Vec<f64>, String> {
    let v: Vec<f64> = group
        .split_whitespace()
        .map(|t| {
            t.parse::<f64>()
                .map_err(|_| format!("{t:?} is not a number"))
        })
        .collect::<Result<_, _>>()?;
    if v.len() != n {
        return Err(format!("{} values, expected {n}", v.len()));
    }
    if let Some(x) = v.iter().find(|x| !x.is_finite()) {
        return Err(format!("value {x} is not finite"));
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    const SAMPLE: &str = "fr 21753\r\nts 39596.024831\r\n6dcal 2\r\n6d 1 [0 1.000][-475.292 -567.632 -53.704 135.5743 5.7618 -3.3069][0.993291 0.111352 0.031199 0.057393 -0.708916 0.702954 0.100393 -0.696447 -0.710551]\r\n";

    #[test]
    fn parses_the_design_sample() {
        let f = parse_datagram(SAMPLE).unwrap();
        assert_eq!(f.frame, Some(21753));
        assert_eq!(f.timestamp, Some(39596.024831));
        assert_eq!(f.calibrated, Some(2));
        assert_eq!(f.bodies.len(), 1);
        let b = &f.bodies[0];
        assert_eq!((b.id, b.quality), (0, 1.0));
        assert!((b.position - DVec3::new(-0.475292, -0.567632, -0.053704)).length() < 1e-12);
        // Column-wise: the first three numbers are the first column.
        assert_eq!(b.rotation.x_axis, DVec3::new(0.993291, 0.111352, 0.031199));
        assert_eq!(
            b.rotation.col(2),
            DVec3::new(0.100393, -0.696447, -0.710551)
        );
        // The line's angles agree with the matrix read column-wise, with
        // R = Rx(eta) Ry(theta) Rz(phi): eta = atan2(-R12, R22), theta = asin(R02).
        let r = b.rotation;
        let eta = (-r.z_axis.y).atan2(r.z_axis.z).to_degrees();
        let theta = r.z_axis.x.asin().to_degrees();
        let phi = (-r.y_axis.x).atan2(r.x_axis.x).to_degrees();
        assert!((eta - 135.5743).abs() < 1e-3, "{eta}");
        assert!((theta - 5.7618).abs() < 1e-3, "{theta}");
        assert!((phi - -3.3069).abs() < 1e-3, "{phi}");
    }

    #[test]
    fn untracked_bodies_and_unknown_lines() {
        let text = "fr 1\n3d 0\n6d 2 [0 -1.000][0 0 0 0 0 0][0 0 0 0 0 0 0 0 0] [3 0.9][1000 0 0 0 0 0][1 0 0 0 1 0 0 0 1]\ngl 0\n";
        let f = parse_datagram(text).unwrap();
        assert_eq!(f.bodies.len(), 2);
        assert!(!f.bodies[0].is_tracked());
        assert!(f.bodies[1].is_tracked());
        assert_eq!(f.bodies[1].position, DVec3::X);
    }

    #[track_caller]
    fn check_err(text: &str, expected: &str) {
        let e = parse_datagram(text).unwrap_err().to_string();
        assert!(e.contains(expected), "{e:?} lacks {expected:?}");
    }

    #[test]
    fn bad_datagrams_name_the_line_and_problem() {
        check_err("fr x", "dtrack line 1 (fr): bad frame counter");
        check_err("fr 1\nts nan", "line 2 (ts): timestamp NaN is not finite");
        check_err(
            "6d 2 [0 1][0 0 0 0 0 0][1 0 0 0 1 0 0 0 1]",
            "2 bodies announced but 3 bracket groups",
        );
        check_err(
            "6d 1 [0 1][0 0 inf 0 0 0][1 0 0 0 1 0 0 0 1]",
            "value inf is not finite",
        );
        check_err(
            "6d 1 [0 1][0 0 0 0 0][1 0 0 0 1 0 0 0 1]",
            "5 values, expected 6",
        );
        check_err(
            "6d 1 [0 1][0 0 0 0 0 0][2 0 0 0 1 0 0 0 1]",
            "rotation is not a rotation",
        );
        check_err("6d 1 [0 1][0 0 0 0 0 0][1 0 0 0 1 0 0 0 1", "unterminated");
        check_err(
            "6d 1 [-1 1][0 0 0 0 0 0][1 0 0 0 1 0 0 0 1]",
            "id -1 is not",
        );
    }

    proptest::proptest! {
        #[test]
        fn never_panics(s in "\\PC{0,200}") {
            let _ = parse_datagram(&s);
        }

        #[test]
        fn mutated_samples_never_panic(i in 0usize..300, c in proptest::char::any()) {
            let mut s: Vec<char> = SAMPLE.chars().collect();
            let i = i % s.len();
            s[i] = c;
            let s: String = s.into_iter().collect();
            if let Ok(f) = parse_datagram(&s) {
                for b in f.bodies {
                    proptest::prop_assert!(b.position.is_finite());
                }
            }
        }
    }
}
