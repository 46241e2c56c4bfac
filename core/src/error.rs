//! Error types of the core. Third-party errors are rendered into messages, never exposed.

use std::path::PathBuf;

/// Where in a file something is wrong.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Location {
    /// The file, as the user named it.
    pub file: PathBuf,
    /// 1-based line, when known.
    pub line: Option<usize>,
    /// 1-based column, when known.
    pub column: Option<usize>,
}

/// One problem found in a robot file: where it is, which field, and what was expected.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Issue {
    /// Dotted field path, e.g. `kinematics.joints[2].limits`.
    pub path: String,
    /// What is wrong and what was expected.
    pub message: String,
    /// 1-based line in the file, when it could be found.
    pub line: Option<usize>,
}

impl Issue {
    /// A problem at `path`; the line is filled in by the loader.
    pub fn new(path: impl Into<String>, message: impl Into<String>) -> Self {
        Issue {
            path: path.into(),
            message: message.into(),
            line: None,
        }
    }

    /// `file:line: path: message`, leaving out the line when unknown and the path when empty
    /// (an issue of the whole file, or one whose message names its element itself).
    pub fn in_file(&self, file: &std::path::Path) -> String {
        let line = self.line.map(|l| format!(":{l}")).unwrap_or_default();
        format!("{}{line}: {}", file.display(), self.in_model())
    }

    /// `path: message`, or the message alone when the path is empty.
    fn in_model(&self) -> String {
        if self.path.is_empty() {
            self.message.clone()
        } else {
            format!("{}: {}", self.path, self.message)
        }
    }
}

/// A list of [`Issue`]s collected while checking a file.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Issues(pub Vec<Issue>);

impl Issues {
    /// Records a problem.
    pub fn push(&mut self, path: impl Into<String>, message: impl Into<String>) {
        self.0.push(Issue::new(path, message));
    }
    /// True when nothing was recorded.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

/// Errors of the core library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        message: String,
    },
    /// A file is not valid: every problem, each with its field and line.
    #[error("{}", render_issues(file, issues))]
    InvalidFile {
        /// The file.
        file: PathBuf,
        /// The problems found.
        issues: Vec<Issue>,
    },
    /// A model could not be built from its description (no file context).
    #[error("invalid model: {}", .0.iter().map(Issue::in_model).collect::<Vec<_>>().join("; "))]
    InvalidModel(Vec<Issue>),
    /// Wrong number of values, e.g. joint values for a robot with another joint count.
    #[error("{what}: expected {expected} values, got {got}")]
    Dimension {
        /// What was given.
        what: String,
        /// How many were expected.
        expected: usize,
        /// How many were given.
        got: usize,
    },
    /// Anything else a caller gave that cannot be used, with the reason.
    #[error("{0}")]
    Input(String),
    /// Stopped on request (see [`crate::interrupt`]) before the result was complete.
    #[error("interrupted")]
    Interrupted,
}

fn render_issues(file: &std::path::Path, issues: &[Issue]) -> String {
    issues.iter().map(|i| i.in_file(file)).collect::<Vec<_>>().join("\n")
}

/// Result with the core's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn issues_name_file_line_and_field_once() {
        let issue = |path: &str, line| Issue {
            path: path.into(),
            message: "expected a number".into(),
            line,
        };
        let err = Error::InvalidFile {
            file: PathBuf::from("arm.toml"),
            issues: vec![
                issue("links[0].mass", Some(4)),
                issue("", Some(7)),
                issue("", None),
                issue("units", None),
            ],
        };
        assert_eq!(
            err.to_string(),
            "arm.toml:4: links[0].mass: expected a number\narm.toml:7: expected a number\n\
             arm.toml: expected a number\narm.toml: units: expected a number"
        );
        let model = Error::InvalidModel(vec![issue("j1", None), issue("", None)]);
        assert_eq!(
            model.to_string(),
            "invalid model: j1: expected a number; expected a number"
        );
    }
}
