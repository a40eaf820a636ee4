//! A.R.T. DTrack ASCII output (DESIGN section 6a): one UDP datagram per
//! frame, lines `fr`, `ts`, `6dcal` and `6d`; other lines are ignored.
//! Positions are millimetres, rotation matrices are given column-wise, and
//! quality -1 means the body is not tracked.
//!
//! Datagrams come off the network, so every input gives `Ok` or an `Err`
//! naming the line and problem, never a panic: counts are bounded before
//! any arithmetic, and messages quote at most [`QUOTE_CHARS`] of the input.

use glam::{DMat3, DVec3};

/// Most bodies a `6d` line may announce. DTrack numbers its calibrated
/// bodies in the tens to hundreds, and a 64 KiB UDP datagram holds at most
/// about 1800 body blocks, so a larger count is not a DTrack datagram.
pub const MAX_BODIES: usize = 1000;

/// Most characters of the input an error message quotes.
pub const QUOTE_CHARS: usize = 24;

/// `s` for an error message: at most [`QUOTE_CHARS`] characters, debug-quoted.
fn quote(s: &str) -> String {
    match s.char_indices().nth(QUOTE_CHARS) {
        Some((end, _)) => format!("{:?}...", &s[..end]),
        None => format!("{s:?}"),
    }
}

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
                        .map_err(|_| err(format!("bad frame counter {}", quote(rest))))?,
                )
            }
            "ts" => {
                let ts: f64 = rest
                    .parse()
                    .map_err(|_| err(format!("bad timestamp {}", quote(rest))))?;
                if !ts.is_finite() {
                    return Err(err(format!("timestamp {ts} is not finite")));
                }
                out.timestamp = Some(ts);
            }
            "6dcal" => {
                out.calibrated = Some(
                    rest.parse()
                        .map_err(|_| err(format!("bad body count {}", quote(rest))))?,
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
        .map_err(|_| format!("bad body count {}", quote(count.trim())))?;
    // Bounded before any arithmetic: `3 * count` once wrapped around to the
    // number of groups found and let a short line through to the indexing.
    let expected = count
        .checked_mul(3)
        .filter(|_| count <= MAX_BODIES)
        .ok_or_else(|| {
            format!(
                "body count {count} is above the {MAX_BODIES} bodies a DTrack datagram can hold"
            )
        })?;
    let groups = brackets(blocks)?;
    if groups.len() != expected {
        return Err(format!(
            "{count} bodies announced but {} bracket groups found (expected {expected})",
            groups.len(),
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
                // Huge entries overflow to inf (or inf - inf = NaN), which
                // `f64::max` would skip: NaN counts as the worst error.
                let err = (rotation.transpose() * rotation - DMat3::IDENTITY)
                    .to_cols_array()
                    .iter()
                    .fold(0.0f64, |m, x| {
                        if x.is_nan() {
                            f64::INFINITY
                        } else {
                            m.max(x.abs())
                        }
                    });
                if !(err <= 1e-3 && rotation.determinant() > 0.0) {
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
            return Err(format!("expected '[' at {}", quote(rest)));
        };
        let Some(end) = after.find(']') else {
            return Err("unterminated '['".into());
        };
        out.push(&after[..end]);
        rest = after[end + 1..].trim_start();
    }
    Ok(out)
}

/// Exactly `n` finite numbers; reads at most `n + 1` tokens of the group.
fn numbers(group: &str, n: usize) -> Result<Vec<f64>, String> {
    let mut tokens = group.split_whitespace();
    let v: Vec<f64> = tokens
        .by_ref()
        .take(n)
        .map(|t| {
            t.parse::<f64>()
                .map_err(|_| format!("{} is not a number", quote(t)))
        })
        .collect::<Result<_, _>>()?;
    if v.len() != n {
        return Err(format!("{} values, expected {n}", v.len()));
    }
    if tokens.next().is_some() {
        return Err(format!("more than {n} values, expected {n}"));
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

    /// A body count whose triple wraps around `usize` (to 1) must not pass
    /// the bracket-group check and then index past the one group found.
    #[test]
    fn a_body_count_that_wraps_is_refused() {
        const CRASH: &str = "6d 12297829382473034411 [0 1.000]";
        assert_eq!(12297829382473034411usize.wrapping_mul(3), 1);
        check_err(CRASH, "dtrack line 1 (6d): body count 12297829382473034411");
        check_err(&format!("fr 1\r\nts 2.5\r\n{CRASH}\r\n"), "line 3 (6d)");
        check_err("6d 18446744073709551615 [0 1.000]", "body count");
    }

    #[test]
    fn hostile_numbers_and_sizes_give_short_errors() {
        check_err("fr 18446744073709551616", "bad frame counter");
        check_err("6dcal 4294967296", "bad body count");
        check_err("6d 1001 ", "body count 1001 is above the 1000");
        check_err(
            "6d 1 [0 1][0 0 0 0 0 0 0][1 0 0 0 1 0 0 0 1]",
            "more than 6 values, expected 6",
        );
        check_err(
            "6d 1 [4294967296 1][0 0 0 0 0 0][1 0 0 0 1 0 0 0 1]",
            "id 4294967296 is not",
        );
        // R^T R overflows to inf and inf - inf: still not a rotation.
        check_err(
            "6d 1 [0 1][0 0 0 0 0 0][1e200 1e200 0 -1e200 1e200 0 0 0 1]",
            "rotation is not a rotation",
        );
        check_err(
            "6d 1 [0 1][0 0 0 0 0 0][-1 0 0 0 -1 0 0 0 -1]",
            "rotation is not a rotation",
        );
        // Untracked bodies may carry any finite numbers; positions stay finite.
        let f =
            parse_datagram("6d 1 [0 -1][1.7976931348623157e308 0 0 0 0 0][1e308 0 0 0 0 0 0 0 0]")
                .unwrap();
        assert!(f.bodies[0].position.is_finite() && !f.bodies[0].is_tracked());
        // An error quotes a bounded excerpt of a huge input.
        let huge = format!("fr {}", "9".repeat(100_000));
        let e = parse_datagram(&huge).unwrap_err().to_string();
        assert!(e.len() < 80, "{e}");
        let e = parse_datagram(&format!("6d 1 [0 1][{} 0 0 0 0 0]", "x".repeat(70_000)))
            .unwrap_err()
            .to_string();
        assert!(e.len() < 100, "{e}");
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
