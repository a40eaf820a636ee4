//! Recorded tracking sessions: JSON Lines, one header line then one line
//! per datagram, `{"t": seconds, "datagram": "<DTrack ASCII>"}`, plus
//! `"rejected": [...]` when the live ingest rejected something in it (the
//! parser's error, or each refused body sample). Recording the raw
//! datagrams (not filtered poses), bad ones included, means a replay goes
//! through the same parser and filter as the live show, so it reproduces it
//! exactly; `rejected` lets the replay check that it did.
//!
//! The recorder flushes every line, so a crash or power loss leaves at
//! most the last line partial: the reader replays up to the last whole
//! line and warns. A bad line anywhere else is corruption, an error.

use serde::{Deserialize, Serialize};
use showcase_proto::config::TrackingConfig;
use std::io::{BufRead, Write};
use std::path::Path;
use tracing::warn;

/// Format name in the header line.
pub const FORMAT: &str = "showcase-tracking";
/// Format version written. Version 2 added `rejected`; version 1 files
/// read the same, without it. (A version 1 reader refuses the new key, so
/// the header says which it is.)
pub const VERSION: u32 = 2;
/// Oldest version still read.
pub const OLDEST_VERSION: u32 = 1;

/// The first line of a recording.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Header {
    /// Always [`FORMAT`].
    pub format: String,
    /// [`OLDEST_VERSION`] to [`VERSION`].
    pub version: u32,
    /// Free text: where and when it was recorded.
    #[serde(default)]
    pub note: String,
    /// The tracking settings of the show that recorded it (body mapping,
    /// room transform, limits), so a replay maps and filters the datagrams
    /// as the live show did. Absent in version 1 files.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tracking: Option<TrackingConfig>,
}

/// One received datagram.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Entry {
    /// Seconds since the start of the recording.
    pub t: f64,
    /// The datagram's text, exactly as received.
    pub datagram: String,
    /// What the live ingest rejected in it: the parser's error, or one
    /// `body <id>: <why>` per refused sample. `Some(empty)`: nothing;
    /// `None`: not known (version 1 recordings).
    #[serde(default, skip_serializing_if = "nothing_rejected")]
    pub rejected: Option<Vec<String>>,
}

fn nothing_rejected(r: &Option<Vec<String>>) -> bool {
    r.as_ref().is_none_or(Vec::is_empty)
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

/// The last line of a recording cut short by a crash or power loss.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "{file}:{line}: the last line is incomplete ({problem}), as a crash or power loss leaves it; replaying the lines before it"
)]
pub struct Cut {
    /// The file.
    pub file: String,
    /// 1-based line number of the partial line.
    pub line: usize,
    /// Why it does not read.
    pub problem: String,
}

/// A recording as read.
#[derive(Clone, Debug, PartialEq)]
pub struct Recording {
    /// The header.
    pub header: Header,
    /// Every whole datagram line.
    pub entries: Vec<Entry>,
    /// The partial last line that was left out, if any.
    pub cut: Option<Cut>,
}

/// Read a whole recording, checking the header and that times are finite
/// and never decrease; warns when the last line was cut short. Datagrams
/// are not parsed here: bad ones are data, rejected again by the replay.
pub fn read(path: &Path) -> Result<Vec<Entry>, RecordingError> {
    let r = read_recording(path)?;
    r.warn_if_cut();
    Ok(r.entries)
}

impl Recording {
    /// Log the cut last line, if any.
    pub fn warn_if_cut(&self) {
        if let Some(cut) = &self.cut {
            warn!(file = %cut.file, line = cut.line, "{cut}");
        }
    }
}

/// [`read`], reporting a cut instead of logging it.
pub fn read_recording(path: &Path) -> Result<Recording, RecordingError> {
    let file = path.display().to_string();
    let f = std::fs::File::open(path).map_err(|error| RecordingError::Io {
        file: file.clone(),
        error,
    })?;
    parse_recording(std::io::BufReader::new(f), &file)
}

/// [`read_recording`] from any reader (`file` names it in errors).
pub fn parse_recording(mut reader: impl BufRead, file: &str) -> Result<Recording, RecordingError> {
    let err = |line: usize, problem: String| RecordingError::Format {
        file: file.to_owned(),
        line,
        problem,
    };
    let mut buf = Vec::new();
    let mut next_line = |buf: &mut Vec<u8>| -> Result<bool, RecordingError> {
        buf.clear();
        reader
            .read_until(b'\n', buf)
            .map(|n| n > 0)
            .map_err(|error| RecordingError::Io {
                file: file.to_owned(),
                error,
            })
    };
    if !next_line(&mut buf)? {
        return Err(err(1, "empty file: expected a header line".into()));
    }
    let header: Header = std::str::from_utf8(&buf)
        .map_err(|e| e.to_string())
        .and_then(|l| serde_json::from_str(l).map_err(|e| e.to_string()))
        .map_err(|e| err(1, format!("bad header: {e}")))?;
    if header.format != FORMAT || !(OLDEST_VERSION..=VERSION).contains(&header.version) {
        return Err(err(
            1,
            format!(
                "format {:?} version {} is not {FORMAT} version {OLDEST_VERSION} to {VERSION}",
                header.format, header.version
            ),
        ));
    }
    let mut entries = Vec::new();
    let mut last = f64::NEG_INFINITY;
    // A line that does not read is an error unless no line follows it.
    let mut unread: Option<(usize, String)> = None;
    let mut n = 1;
    while next_line(&mut buf)? {
        n += 1;
        if buf.trim_ascii().is_empty() {
            continue;
        }
        if let Some((line, problem)) = unread.take() {
            return Err(err(line, problem));
        }
        let entry = std::str::from_utf8(&buf)
            .map_err(|e| format!("not UTF-8: {e}"))
            .and_then(|l| serde_json::from_str::<Entry>(l).map_err(|e| e.to_string()));
        let mut e = match entry {
            Ok(e) => e,
            Err(problem) => {
                unread = Some((n, problem));
                continue;
            }
        };
        if !e.t.is_finite() || e.t < last {
            return Err(err(
                n,
                format!(
                    "time {} is not finite or goes backwards (after {last})",
                    e.t
                ),
            ));
        }
        if header.version >= 2 {
            e.rejected.get_or_insert_default();
        }
        last = e.t;
        entries.push(e);
    }
    let cut = unread.map(|(line, problem)| Cut {
        file: file.to_owned(),
        line,
        problem,
    });
    Ok(Recording {
        header,
        entries,
        cut,
    })
}

/// Writes a recording as datagrams arrive; flushes every line so that a
/// crash loses at most the line being written.
#[derive(Debug)]
pub struct Recorder<W: Write> {
    out: W,
}

impl<W: Write> Recorder<W> {
    /// Start a recording with a header line that keeps the show's
    /// tracking settings.
    pub fn new(mut out: W, note: &str, tracking: Option<&TrackingConfig>) -> std::io::Result<Self> {
        let h = Header {
            format: FORMAT.into(),
            version: VERSION,
            note: note.into(),
            tracking: tracking.cloned(),
        };
        writeln!(out, "{}", serde_json::to_string(&h)?)?;
        out.flush()?;
        Ok(Self { out })
    }

    /// Append one datagram received at `t` seconds, with nothing rejected.
    pub fn record(&mut self, t: f64, datagram: &str) -> std::io::Result<()> {
        self.record_entry(&Entry {
            t,
            datagram: datagram.into(),
            rejected: None,
        })
    }

    /// Append one entry, with what was rejected in it.
    pub fn record_entry(&mut self, e: &Entry) -> std::io::Result<()> {
        writeln!(self.out, "{}", serde_json::to_string(e)?)?;
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

    /// The entries of a recording read from bytes.
    fn parse(reader: impl BufRead, file: &str) -> Result<Vec<Entry>, RecordingError> {
        parse_recording(reader, file).map(|r| r.entries)
    }

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
        let mut rec = Recorder::new(Vec::new(), "test", None).unwrap();
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
        let e = parse(&b""[..], "s.jsonl").unwrap_err().to_string();
        assert_eq!(e, "s.jsonl:1: empty file: expected a header line");
        let e = parse(&b"{\"format\":\"x\",\"version\":1}\n"[..], "s.jsonl")
            .unwrap_err()
            .to_string();
        assert!(e.contains("is not showcase-tracking"), "{e}");
        let e = parse(
            &b"{\"format\":\"showcase-tracking\",\"version\":3}\n"[..],
            "s.jsonl",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.ends_with("version 3 is not showcase-tracking version 1 to 2"),
            "{e}"
        );
    }

    /// A live session records every datagram it received, including those
    /// the parser refused (`session.jsonl:165: dtrack line 2 (6d):
    /// expected '['` used to refuse the whole file): they are data, and
    /// the replay rejects them again the same way.
    #[test]
    fn datagrams_the_parser_refuses_are_read_back() {
        let mut rec = Recorder::new(Vec::new(), "test", None).unwrap();
        rec.record(0.0, "fr 1\n6d 0\n").unwrap();
        let bad = [
            "fr 2\n6d 1 [0 1][1 2 3 0 0 0] x[1 0 0 0 1 0 0 0 1]\n",
            "6d 12297829382473034411 [0 1.000]",
            "fr 3\n6d 1 [0 1][1 2 nan 0 0 0][1 0 0 0 1 0 0 0 1]\n",
        ];
        for (i, d) in bad.iter().enumerate() {
            let why = crate::tracking::parse_datagram(d).unwrap_err().to_string();
            rec.record_entry(&Entry {
                t: 0.1 * (i + 1) as f64,
                datagram: (*d).into(),
                rejected: Some(vec![why]),
            })
            .unwrap();
        }
        let entries = parse(&rec.into_inner()[..], "session.jsonl").unwrap();
        assert_eq!(entries.len(), 4);
        assert_eq!(entries[0].rejected, Some(vec![]));
        assert_eq!(entries[1].datagram, bad[0]);
        assert_eq!(
            entries[1].rejected.as_deref(),
            Some(&["dtrack line 2 (6d): expected '[' at \"x[1 0 0 0 1 0 0 0 1]\"".to_owned()][..])
        );
    }

    /// Version 1 files (no `rejected`) still read; what they rejected is
    /// unknown, where a version 2 line without the key rejected nothing.
    #[test]
    fn version_1_recordings_still_read() {
        let v1 = "{\"format\":\"showcase-tracking\",\"version\":1,\"note\":\"old\"}\n\
                  {\"t\":0.0,\"datagram\":\"fr 1\\n6d 0\\n\"}\n";
        let r = parse_recording(v1.as_bytes(), "old.jsonl").unwrap();
        assert_eq!((r.header.version, r.entries.len()), (1, 1));
        assert_eq!(r.entries[0].rejected, None);
        let v2 = v1.replace("\"version\":1", "\"version\":2");
        let r = parse_recording(v2.as_bytes(), "new.jsonl").unwrap();
        assert_eq!(r.entries[0].rejected, Some(vec![]));
    }

    fn three_lines() -> Vec<u8> {
        let mut rec = Recorder::new(Vec::new(), "test", None).unwrap();
        for i in 0..3 {
            rec.record(f64::from(i) * 0.5, &format!("fr {i}\n6d 0\n"))
                .unwrap();
        }
        rec.into_inner()
    }

    /// A crash or power loss leaves the last line partial, without its
    /// newline, or as garbage (a block of NULs): the recording replays up
    /// to its last whole line, and the cut names the file and line.
    #[test]
    fn a_recording_cut_short_replays_up_to_its_last_whole_line() {
        let whole = three_lines();
        let partial = &whole[..whole.len() - 9];
        let mut nuls = whole.clone();
        nuls.extend_from_slice(&[0; 512]);
        let mut not_utf8 = whole.clone();
        not_utf8.extend_from_slice(b"{\"t\":2.0,\"datagram\":\"fr \xff\xfe");
        let mut garbage_then_blank = whole.clone();
        garbage_then_blank.extend_from_slice(b"{\"t\":2.0,\"data\n\n  \n");
        for (name, bytes, kept, line) in [
            ("partial", partial, 2, 4),
            ("nuls", &nuls[..], 3, 5),
            ("not_utf8", &not_utf8[..], 3, 5),
            ("garbage_then_blank", &garbage_then_blank[..], 3, 5),
        ] {
            let r = parse_recording(bytes, "cut.jsonl").unwrap();
            assert_eq!(r.entries.len(), kept, "{name}");
            let cut = r.cut.expect(name);
            assert_eq!((cut.file.as_str(), cut.line), ("cut.jsonl", line), "{name}");
            assert!(
                cut.to_string()
                    .starts_with(&format!("cut.jsonl:{line}: the last line is incomplete")),
                "{cut}"
            );
            // `read`, which replays use, keeps the same whole lines.
            let path = std::env::temp_dir()
                .join(format!("showcase-cut-{}-{name}.jsonl", std::process::id()));
            std::fs::write(&path, bytes).unwrap();
            assert_eq!(read(&path).unwrap(), r.entries, "{name}");
            std::fs::remove_file(&path).unwrap();
        }
        // A whole file has no cut, with or without its final newline.
        assert_eq!(parse_recording(&whole[..], "w.jsonl").unwrap().cut, None);
        let r = parse_recording(&whole[..whole.len() - 1], "w.jsonl").unwrap();
        assert_eq!((r.entries.len(), r.cut), (3, None));
    }

    /// A bad line with whole lines after it is corruption, not a cut.
    #[test]
    fn a_bad_line_in_the_middle_is_an_error() {
        let text = String::from_utf8(three_lines()).unwrap();
        let mut lines: Vec<&str> = text.lines().collect();
        lines[2] = "{\"t\":0.5,\"datagr";
        let e = parse(lines.join("\n").as_bytes(), "mid.jsonl")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("mid.jsonl:3: "), "{e}");
        let mut bytes = three_lines();
        let at = bytes.iter().rposition(|b| *b == b'f').unwrap();
        bytes[at] = 0xff;
        bytes.extend_from_slice(b"{\"t\":9.0,\"datagram\":\"\"}\n");
        let e = parse(&bytes[..], "mid.jsonl").unwrap_err().to_string();
        assert!(e.starts_with("mid.jsonl:4: not UTF-8"), "{e}");
    }
}
