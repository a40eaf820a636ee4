//! Scene-file errors: each names the scene file and the line or field at
//! fault, plus the mesh or calibration file where one is involved.

/// Why a scene file could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file itself could not be read.
    #[error("{file}: cannot read scene file: {error}")]
    Read {
        /// The scene file.
        file: String,
        /// The I/O failure (shown in the message, so not also a `source`,
        /// which would print it twice in error chains).
        error: std::io::Error,
    },
    /// The text is not a scene: malformed TOML, an unknown key, a value of
    /// the wrong type, a missing key, or a non-finite number.
    #[error("{file}:{line}:{column}: {message}")]
    Syntax {
        /// The scene file.
        file: String,
        /// 1-based line of the offending value (0 when unknown).
        line: usize,
        /// 1-based column of the offending value (0 when unknown).
        column: usize,
        /// What is wrong, with the source line it was found on.
        message: String,
    },
    /// A well-formed value that does not make a valid scene: a degenerate
    /// device matrix, an unknown part name, a duplicate name, a rule of
    /// `showcase_proto::Validate` broken.
    #[error("{file}: {field}: {problem}")]
    Invalid {
        /// The scene file.
        file: String,
        /// The offending field, e.g. `projector[1] 'projector-1'.rotation`.
        field: String,
        /// What is wrong with it.
        problem: String,
    },
    /// A mesh file given as the whole scene (see [`super::load_any`]) could
    /// not be read or parsed.
    #[error("{file}{}: {problem}", line.map(|l| format!(":{l}")).unwrap_or_default())]
    Mesh {
        /// The mesh file.
        file: String,
        /// The 1-based line in the mesh file, when known.
        line: Option<usize>,
        /// What is wrong with it.
        problem: String,
    },
    /// A mesh or calibration file referenced by the scene could not be read
    /// or parsed.
    #[error("{file}: {field}: {referenced}{}: {problem}", line.map(|l| format!(":{l}")).unwrap_or_default())]
    Referenced {
        /// The scene file.
        file: String,
        /// The field that references the file, e.g. `object[0] 'room'.mesh`.
        field: String,
        /// The referenced file, as resolved against the scene's folder.
        referenced: String,
        /// The 1-based line in the referenced file, when known.
        line: Option<usize>,
        /// What is wrong with it.
        problem: String,
    },
}

/// Builds errors for one scene file.
#[derive(Clone, Debug)]
pub(crate) struct Ctx {
    pub(crate) file: String,
}

impl Ctx {
    /// An [`SceneError::Invalid`] for `field`.
    pub(crate) fn invalid(
        &self,
        field: impl Into<String>,
        problem: impl Into<String>,
    ) -> SceneError {
        SceneError::Invalid {
            file: self.file.clone(),
            field: field.into(),
            problem: problem.into(),
        }
    }

    /// A [`SceneError::Referenced`] for the file `referenced` named by `field`.
    pub(crate) fn referenced(
        &self,
        field: impl Into<String>,
        referenced: &std::path::Path,
        line: Option<usize>,
        problem: impl Into<String>,
    ) -> SceneError {
        SceneError::Referenced {
            file: self.file.clone(),
            field: field.into(),
            referenced: referenced.display().to_string(),
            line,
            problem: problem.into(),
        }
    }

    /// Turn a TOML error into a [`SceneError::Syntax`] with line, column and
    /// the source line.
    pub(crate) fn syntax(&self, text: &str, e: &toml::de::Error) -> SceneError {
        let message = e.message().trim_end().replace('\n', "; ");
        let Some(span) = e.span() else {
            return SceneError::Syntax {
                file: self.file.clone(),
                line: 0,
                column: 0,
                message,
            };
        };
        let (line, column, source) = locate(text, span.start);
        let source = source.trim();
        let message = if span.is_empty() && span.start == 0 {
            // toml points at the document itself for a key missing at the
            // top level: the first line is not where the problem is.
            format!("{message}, at the top level of the file")
        } else if source.is_empty() {
            message
        } else {
            let shown: String = source.chars().take(120).collect();
            format!("{message}, in `{shown}`")
        };
        SceneError::Syntax {
            file: self.file.clone(),
            line,
            column,
            message,
        }
    }
}

/// 1-based line and column of byte `offset` in `text`, and that line.
fn locate(text: &str, offset: usize) -> (usize, usize, &str) {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let line_end = text[offset..].find('\n').map_or(text.len(), |i| offset + i);
    let line = before.matches('\n').count() + 1;
    let column = text[line_start..offset].chars().count() + 1;
    (line, column, &text[line_start..line_end])
}

#[cfg(test)]
mod tests {
    use super::locate;

    #[test]
    fn locate_counts_lines_and_columns_from_one() {
        let t = "a = 1\nbb = 2\n";
        assert_eq!(locate(t, 0), (1, 1, "a = 1"));
        assert_eq!(locate(t, 6), (2, 1, "bb = 2"));
        assert_eq!(locate(t, 11), (2, 6, "bb = 2"));
        // Past the end and inside a multi-byte character stay in range.
        assert_eq!(locate(t, 999).0, 3);
        assert_eq!(locate("é = 1", 1), (1, 1, "é = 1"));
    }
}
