//! Recorded tracking sessions: JSON Lines, one header line then one line
//! per datagram, `{"t": seconds, "datagram": "<DTrack ASCII>"}`. Recording
//! the raw datagrams (not filtered poses) means a replay goes through the
//! same parser and filter as the live show, so it reproduces it exactly.

use serde::{Deserialize, Serialize};
use std::io::{BufRead, Write};
use std::path::Path;

/// Format name in the header line.
pub const FORMAT: &str = "showcase-tracking";
/// Format version in the header line.
pub const VERSION: u32 = 1;

/// The first line of a recording.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Header {
    /// Always [`FORMAT`].
    pub format: String,
    /// Always [`VERSION`].
    pub version: u32,
    /// Free text: where and when it was recorded.
    #[serde(default)]
    pub note: String,
}

/// One received datagram.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Entry {
    /// Seconds since the start of the recording.
    pub t: f64,
    /// The datagram's text.
    pub datagram: String,
}

/// A recording that cannot be read; names the file and line.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The file could not be read or written.
    #[error("{file}: {error}")]
    Io {
        /// The file.
        file: String,
        /// The IO error.
        error: std::io::Error,
    },
    /// A line is not what the format says.
    #[error("{file}:{line}: {problem}")]
    Format {
        /// The file.
        file: String,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        problem: String,
    },
}

/// Read a whole recording, checking the header, that times are finite and
/// never decrease, and that every datagram parses.
pub fn read(path: &Path) -> Result<Vec<Entry>, RecordingError> {
    let file = path.display().to_string();
    let f = std::fs::File::open(path).map_err(|error| RecordingError::Io {
        file: file.clone(),
        error,
    })?;
    parse(std::io::BufReader::new(f), &file)
}

/// Parse a recording from any reader; `file` names it in errors.
pub fn parse(reader: impl BufRead, file: &str) -> Result<Vec<Entry>, RecordingError> {
    let err = |line: usize, problem: String| RecordingError::Format {
        file: file.to_owned(),
        line,
        problem,
    };
    let mut lines = reader.lines().enumerate();
    let header = match lines.next() {
        Some((_, l)) => l.map_err(|error| RecordingError::Io {
            file: file.to_owned(),
            error,
        })?,
        None => return Err(err(1, "empty file: expected a header line".into())),
    };
    let h: Header =
        serde_json::from_str(&header).map_err(|e| err(1, format!("bad header: {e}")))?;
    if h.format != FORMAT || h.version != VERSION {
        return Err(err(
            1,
            format!(
                "format {:?} version {} is not {FORMAT} version {VERSION}",
                h.format, h.version
            ),
        ));
    }
    let mut out = Vec::new();
    let mut last = f64::NEG_INFINITY;
    for (i, l) in lines {
        let n = i + 1;
        let l = l.map_err(|error| RecordingError::Io {
            file: file.to_owned(),
            error,
        })?;
        if l.trim().is_empty() {
            continue;
        }
        let e: Entry = serde_json::from_str(&l).map_err(|e| err(n, e.to_string()))?;
        if !e.t.is_finite() || e.t < last {
            return Err(err(
                n,
                format!(
                    "time {} is not finite or goes backwards (after {last})",
                    e.t
                ),
            ));
        }
        super::dtrack::parse_datagram(&e.datagram).map_err(|e| err(n, e.to_string()))?;
        last = e.t;
        out.push(e);
    }
    Ok(out)
}

/// Writes a recording as datagrams arrive; flushes every line so that a
/// crash loses at most the line being written.
#[derive(Debug)]
pub struct Recorder<W: Write> {
    out: W,
}

impl<W: Write> Recorder<W> {
    /// Start a recording with a header line.
    pub fn new(mut out: W, note: &str) -> std::io::Result<Self> {
        let h = Header {
            format: FORMAT.into(),
            version: VERSION,
            note: note.into(),
        };
        writeln!(out, "{}", serde_json::to_string(&h)?)?;
        out.flush()?;
        Ok(Self { out })
    }

    /// Append one datagram received at `t` seconds.
    pub fn record(&mut self, t: f64, datagram: &str) -> std::io::Result<()> {
        let e = Entry {
            t,
            datagram: datagram.into(),
        };
        writeln!(self.out, "{}", serde_json::to_string(&e)?)?;
        self.out.flush()
    }

    /// The underlying writer.
    pub fn into_inner(self) -> W {
        self.out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file that cannot be read is named with the reason once: the
    /// message holds the IO error, and the error does not chain it again
    /// (`{:#}` printed it twice).
    #[test]
    fn an_unreadable_file_is_named_with_its_reason_once() {
        let path = std::env::temp_dir().join(format!("no-such-{}.jsonl", std::process::id()));
        let e = anyhow::Error::from(read(&path).unwrap_err());
        let text = format!("{e:#}");
        assert!(text.starts_with(&path.display().to_string()), "{text}");
        assert_eq!(text.matches("(os error").count(), 1, "{text}");
    }

    #[test]
    fn round_trips_and_names_bad_lines() {
        let mut rec = Recorder::new(Vec::new(), "test").unwrap();
        rec.record(0.0, "fr 1\n6d 0\n").unwrap();
        rec.record(0.5, "fr 2\n6d 1 [0 1][1 2 3 0 0 0][1 0 0 0 1 0 0 0 1]\n")
            .unwrap();
        let bytes = rec.into_inner();
        let entries = parse(&bytes[..], "s.jsonl").unwrap();
        assert_eq!(entries.len(), 2);
        assert_eq!(entries[1].t, 0.5);

        let text = String::from_utf8(bytes).unwrap();
        let bad = text.replace("0.5", "-1.0");
        let e = parse(bad.as_bytes(), "s.jsonl").unwrap_err().to_string();
        assert!(e.starts_with("s.jsonl:3: time -1"), "{e}");
        let bad = text.replace("[1 2 3 0 0 0]", "[1 2 nan 0 0 0]");
        let e = parse(bad.as_bytes(), "s.jsonl").unwrap_err().to_string();
        assert!(e.starts_with("s.jsonl:3: dtrack line 2 (6d)"), "{e}");
        let e = parse(&b""[..], "s.jsonl").unwrap_err().to_string();
        assert_eq!(e, "s.jsonl:1: empty file: expected a header line");
        let e = parse(&b"{\"format\":\"x\",\"version\":1}\n"[..], "s.jsonl")
            .unwrap_err()
            .to_string();
        assert!(e.contains("is not showcase-tracking"), "{e}");
    }
}
