//! Error types of the core. Third-party errors are rendered into messages, never exposed.

use std::path::PathBuf;

use crate::role::Role;

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

impl Location {
    /// The whole file.
    pub fn file(file: impl Into<PathBuf>) -> Self {
        Location {
            file: file.into(),
            line: None,
            column: None,
        }
    }

    /// A line of the file.
    pub fn line(file: impl Into<PathBuf>, line: usize) -> Self {
        Location {
            line: Some(line),
            ..Location::file(file)
        }
    }
}

/// `file`, `file:line` or `file:line:column`, as compilers print them.
impl std::fmt::Display for Location {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
            if let Some(c) = self.column {
                write!(f, ":{c}")?;
            }
        }
        Ok(())
    }
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
    pub(crate) fn in_model(&self) -> String {
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

/// How messages about plugin libraries the policy refuses to load begin, so that a caller
/// holding only the message (an [`Issue`]) can tell a library not loaded from a broken one.
pub const NOT_ALLOWED: &str = "run-time plugins are not allowed";

/// Errors of the core library and of the plugins. Each kind of failure has its variant with the
/// values a caller may act on; the message names them all. New kinds may be added, so a `match`
/// needs a catch-all arm.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A file could not be read or written, or may not be written (an output that would replace
    /// an input, a read-only or foreign file, a missing folder).
    #[error("{}: {message}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What kind of failure: the operating system's, or the nearest one for a refusal
        /// (a missing folder `NotFound`, a read-only file `PermissionDenied`, an output that
        /// would replace an input `InvalidInput`).
        kind: std::io::ErrorKind,
        /// The operating system's error code (errno on Unix) when it said no.
        os_code: Option<i32>,
        /// What the operating system said, or why the file is refused.
        message: String,
    },
    /// A robot (or URDF) file is not valid: every problem, each with its field and line.
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
    /// A user's input file (measurements, targets, poses) is wrong at a place: the file alone
    /// when the problem is the whole file (missing, too big), else its line and column.
    #[error("{location}: {message}")]
    InputAt {
        /// Where.
        location: Location,
        /// The column the problem is in, by its name or header cell (`x[mm]`), when it is one.
        column: Option<String>,
        /// What is wrong there and what was expected (naming the column or field).
        message: String,
    },
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
    /// A value given through the API or on the command line cannot be used: a noise that is
    /// not positive, a fold count beyond the poses, a non-finite joint value, a hyper-parameter
    /// out of its range, a fitted predictor whose arrays disagree.
    #[error("{what}: {reason}")]
    InvalidArgument {
        /// The value, by the name its caller knows it (`measurement noise`, `search.bound`,
        /// `sample 3`).
        what: String,
        /// What is wrong with it and what was expected.
        reason: String,
    },
    /// A size asked for (poses, pool, draws, folds, rows, columns) costs more memory or time
    /// than a request may take (see [`crate::support::limits`]).
    #[error("{what} {asked}: at most {limit} {unit}; {reason}")]
    TooLarge {
        /// The size, by the name its caller knows it (`--n`, `--pool`, `columns`).
        what: String,
        /// The size asked for.
        asked: usize,
        /// What it counts (`poses`, `rows`).
        unit: String,
        /// The largest size that fits.
        limit: usize,
        /// What the asked size would cost, and the limits.
        reason: String,
    },
    /// The inputs leave a computation without a unique answer: a matrix that is not positive
    /// definite, features that depend on each other. More or other data (or a regulariser)
    /// helps; the same call again does not.
    #[error("{what}: {reason}")]
    Degenerate {
        /// The computation (`pose selection`, `gp`).
        what: String,
        /// What is singular, and what to change.
        reason: String,
    },
    /// An iterative solver gave up before its tolerance was met.
    #[error("{what} did not converge after {iterations} iterations: {best}")]
    NotConverged {
        /// The solver (`IK`, `gp hyper-parameter fit`).
        what: String,
        /// Iterations done, over all starts.
        iterations: usize,
        /// The best it reached, in words (distance to the target, objective).
        best: String,
    },
    /// No plugin of this role has this `type` name.
    #[error("{provider} has no {role} named `{name}`; it has: {}", backticked(known))]
    UnknownPlugin {
        /// The role that was looked up.
        role: Role,
        /// The name asked for.
        name: String,
        /// The names of that role it has.
        known: Vec<String>,
        /// Where it was looked up: `armcomp` (the built-in plugins) or a library's file name.
        provider: String,
    },
    /// A plugin library speaks another version of the plugin C ABI.
    #[error(
        "{} speaks plugin ABI version {found}, this armcomp speaks version {expected}; rebuild the plugin against this armcomp-sdk",
        library.display()
    )]
    AbiMismatch {
        /// The library file.
        library: PathBuf,
        /// The version this build speaks.
        expected: u32,
        /// The version the library reports.
        found: u32,
    },
    /// The plugin policy does not let this library load (loading runs its code).
    #[error(
        "{NOT_ALLOWED}: loading {} would run its code; pass --allow-plugins to allow it, or list its folder in `plugin_dirs` of the user config",
        library.display()
    )]
    PluginNotAllowed {
        /// The library file.
        library: PathBuf,
    },
    /// A plugin library cannot be used: it cannot be opened or lies outside the folders it may
    /// load from, lacks a symbol its ABI version requires, describes its types wrongly, or a
    /// call into it failed.
    #[error("plugin library {}: {message}", library.display())]
    Plugin {
        /// The library file.
        library: PathBuf,
        /// What is wrong, naming the type or call.
        message: String,
    },
    /// Stopped on request (see [`crate::support::cancel`]) before the result was complete.
    #[error("interrupted")]
    Interrupted,
}

impl Error {
    /// An [`InputAt`](Error::InputAt) error in the input file `path`, at `line` and in the
    /// column headed `column` when known.
    pub fn input_at(path: &std::path::Path, line: Option<usize>, column: Option<&str>, message: String) -> Self {
        Error::InputAt {
            location: Location {
                line,
                ..Location::file(path)
            },
            column: column.map(str::to_string),
            message,
        }
    }

    /// An [`Io`](Error::Io) error for an output `path` whose content could not be produced
    /// (a plot that could not be drawn, a description that could not be serialised).
    pub fn not_written(path: &std::path::Path, message: String) -> Self {
        Error::Io {
            path: path.to_path_buf(),
            kind: std::io::ErrorKind::Other,
            os_code: None,
            message,
        }
    }
}

/// `` `a`, `b` `` or `none`.
fn backticked(names: &[String]) -> String {
    if names.is_empty() {
        "none".into()
    } else {
        names.iter().map(|n| format!("`{n}`")).collect::<Vec<_>>().join(", ")
    }
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

    /// Each typed variant's message names every field it carries, in words a user reads.
    #[test]
    fn typed_variants_name_their_fields() {
        let cases = [
            (
                Error::InputAt {
                    location: Location {
                        line: Some(12),
                        column: Some(3),
                        ..Location::file("poses.csv")
                    },
                    column: Some("x[mm]".into()),
                    message: "column `x[mm]`: `abc` is not a number".into(),
                },
                "poses.csv:12:3: column `x[mm]`: `abc` is not a number",
            ),
            (
                Error::InputAt {
                    location: Location::file("missing.csv"),
                    column: None,
                    message: "does not exist".into(),
                },
                "missing.csv: does not exist",
            ),
            (
                Error::InvalidArgument {
                    what: "measurement noise".into(),
                    reason: "must be positive, got -1 m".into(),
                },
                "measurement noise: must be positive, got -1 m",
            ),
            (
                Error::Degenerate {
                    what: "ridge".into(),
                    reason: "the 10 features are linearly dependent".into(),
                },
                "ridge: the 10 features are linearly dependent",
            ),
            (
                Error::NotConverged {
                    what: "IK".into(),
                    iterations: 240,
                    best: "closest point is 2.000e-3 m from the target".into(),
                },
                "IK did not converge after 240 iterations: closest point is 2.000e-3 m from the target",
            ),
            (
                Error::UnknownPlugin {
                    role: Role::ErrorModel,
                    name: "sag".into(),
                    known: vec!["cable_sag".into(), "hose".into()],
                    provider: "libcable_sag.so".into(),
                },
                "libcable_sag.so has no error model named `sag`; it has: `cable_sag`, `hose`",
            ),
            (
                Error::UnknownPlugin {
                    role: Role::Predictor,
                    name: "gp".into(),
                    known: Vec::new(),
                    provider: "libcable_sag.so".into(),
                },
                "libcable_sag.so has no predictor named `gp`; it has: none",
            ),
            (
                Error::AbiMismatch {
                    library: PathBuf::from("plugins/libold.so"),
                    expected: 4,
                    found: 3,
                },
                "plugins/libold.so speaks plugin ABI version 3, this armcomp speaks version 4; rebuild the plugin \
                 against this armcomp-sdk",
            ),
            (
                Error::Plugin {
                    library: PathBuf::from("plugins/libx.so"),
                    message: "does not export `armcomp_type_info`".into(),
                },
                "plugin library plugins/libx.so: does not export `armcomp_type_info`",
            ),
        ];
        for (err, expected) in cases {
            assert_eq!(err.to_string(), expected);
        }
        let refused = Error::PluginNotAllowed {
            library: PathBuf::from("/opt/libx.so"),
        }
        .to_string();
        // Callers holding only the message tell a refused library by its beginning.
        assert!(refused.starts_with(NOT_ALLOWED), "{refused}");
        assert!(refused.contains("loading /opt/libx.so would run its code"), "{refused}");
    }
}
