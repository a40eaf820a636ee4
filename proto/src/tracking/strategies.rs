//! Proptest strategies for DTrack datagrams and pose samples, hostile ones
//! included: edge and huge numbers, wrong counts, malformed tokens
//! (feature `testing`).

use glam::{DMat3, DQuat, DVec3};
use proptest::collection::vec;
use proptest::prelude::*;

/// Tokens that broke, or nearly broke, parsers: extremes, wrapping counts,
/// non-numbers and numbers Rust's parser treats specially.
fn edge_tokens() -> Vec<String> {
    let mut v: Vec<String> = [
        "0",
        "-0",
        "1",
        "-1",
        "0.5",
        "1e43",
        "-1e43",
        "1e308",
        "1.7976931348623157e308",
        "-1.7976931348623157e308",
        "1e400",
        "-1e400",
        "4.9e-324",
        "nan",
        "NaN",
        "inf",
        "-inf",
        "infinity",
        "+1",
        "1.",
        "-.5",
        "",
        "-",
        "e5",
        "0x10",
        "1_000",
        "12297829382473034411",
        "6148914691236517206",
        "18446744073709551615",
        "18446744073709551616",
        "4294967295",
        "4294967296",
        "1000",
        "1001",
        "[",
        "]",
        "][",
    ]
    .map(String::from)
    .to_vec();
    v.push("9".repeat(400));
    v.push("1".repeat(30) + "e-30");
    v
}

/// One number token: usually a plausible value, often an edge case.
pub fn number_token() -> impl Strategy<Value = String> {
    prop_oneof![
        4 => (-5000.0f64..5000.0).prop_map(|v| format!("{v:.3}")),
        1 => any::<f64>().prop_map(|v| format!("{v}")),
        1 => any::<f64>().prop_map(|v| format!("{v:e}")),
        1 => any::<u64>().prop_map(|v| v.to_string()),
        1 => any::<i64>().prop_map(|v| v.to_string()),
        2 => prop::sample::select(edge_tokens()),
    ]
}

/// A rotation matrix, column-wise as DTrack prints it.
fn rotation_tokens() -> impl Strategy<Value = Vec<String>> {
    let unit = (any::<[i16; 3]>(), -3.2f64..3.2).prop_map(|(axis, angle)| {
        let axis = DVec3::from(axis.map(f64::from))
            .try_normalize()
            .unwrap_or(DVec3::Y);
        DMat3::from_quat(DQuat::from_axis_angle(axis, angle))
            .to_cols_array()
            .iter()
            .map(|v| format!("{v:.6}"))
            .collect()
    });
    prop_oneof![3 => unit, 1 => vec(number_token(), 8..=10)]
}

/// One `[id quality][x y z eta theta phi][rotation]` block, sometimes
/// with the wrong number of values or hostile ones.
pub fn body_block() -> impl Strategy<Value = String> {
    let id = prop_oneof![4 => (0u32..4).prop_map(|i| i.to_string()), 1 => number_token()];
    let quality = prop_oneof![
        2 => Just("1.000".to_owned()),
        1 => Just("-1.000".to_owned()),
        1 => number_token(),
    ];
    let position = prop_oneof![
        3 => vec((-5000.0f64..5000.0).prop_map(|v| format!("{v:.3}")), 6),
        1 => vec(number_token(), 5..=7),
    ];
    (id, quality, position, rotation_tokens())
        .prop_map(|(id, q, p, r)| format!("[{id} {q}][{}][{}]", p.join(" "), r.join(" ")))
}

/// A DTrack-like datagram: `fr`, `ts`, `6dcal` and `6d` lines (and
/// others) with plausible or hostile values, and a `6d` count that usually
/// matches its blocks.
pub fn datagram() -> impl Strategy<Value = String> {
    let frame = prop_oneof![
        any::<u32>().prop_map(|f| format!("fr {f}")),
        number_token().prop_map(|t| format!("fr {t}")),
    ];
    let ts = prop_oneof![
        (0.0f64..86400.0).prop_map(|t| format!("ts {t:.6}")),
        number_token().prop_map(|t| format!("ts {t}")),
    ];
    let cal = number_token().prop_map(|t| format!("6dcal {t}"));
    let six_d = (
        vec(body_block(), 0..4),
        prop::option::weighted(0.2, number_token()),
    )
        .prop_map(|(blocks, count)| {
            let count = count.unwrap_or_else(|| blocks.len().to_string());
            format!("6d {count} {}", blocks.join(""))
        });
    let other = prop::sample::select(vec![
        "3d 0".to_owned(),
        "gl 0".to_owned(),
        "6df2 0".to_owned(),
        String::new(),
        "6d".to_owned(),
    ]);
    let line = prop_oneof![1 => frame, 1 => ts, 1 => cal, 3 => six_d, 1 => other];
    (vec(line, 0..5), any::<bool>()).prop_map(|(lines, crlf)| {
        let sep = if crlf { "\r\n" } else { "\n" };
        lines.iter().map(|l| format!("{l}{sep}")).collect()
    })
}

/// A coordinate: mostly inside a few metres, sometimes wild or not finite.
pub fn coordinate() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => -5.0f64..5.0,
        1 => prop::sample::select(vec![
            4.0, -4.0, 2.5, -1.5, 4.000001, 1e40, -1e40, 1e308, f64::MAX, f64::MIN,
            f64::INFINITY, f64::NEG_INFINITY, f64::NAN, 0.0, -0.0,
        ]),
        1 => any::<f64>(),
    ]
}

/// A rotation as offered to a filter: mostly unit, sometimes degenerate,
/// unnormalised or not finite.
pub fn quaternion() -> impl Strategy<Value = DQuat> {
    prop_oneof![
        4 => (any::<[i16; 3]>(), -3.2f64..3.2).prop_map(|(axis, angle)| {
            let axis = DVec3::from(axis.map(f64::from)).try_normalize().unwrap_or(DVec3::Y);
            DQuat::from_axis_angle(axis, angle)
        }),
        1 => (coordinate(), coordinate(), coordinate(), coordinate())
            .prop_map(|(x, y, z, w)| DQuat::from_xyzw(x, y, z, w)),
    ]
}

/// One sample for a pose filter: (time step, position, rotation). Time
/// steps are mostly small and positive, sometimes zero, negative, huge or
/// not finite.
pub fn sample() -> impl Strategy<Value = (f64, DVec3, DQuat)> {
    let dt = prop_oneof![
        6 => 0.0f64..0.05,
        1 => prop::sample::select(vec![0.0, -0.01, 0.6, 3.0, 1e300, f64::NAN, f64::INFINITY]),
    ];
    (
        dt,
        (coordinate(), coordinate(), coordinate()).prop_map(|(x, y, z)| DVec3::new(x, y, z)),
        quaternion(),
    )
}
