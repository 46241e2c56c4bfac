//! `armcomp validate`: a robot file against the schema, then semantically.

use std::path::{Path, PathBuf};

use armcomp_core::robot::robot_file::SourceFile;
use armcomp_core::support::io::InputLimits;
use armcomp_core::{Error, Robot, RobotFile};
use serde_json::Value;

/// One problem in a file.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Diagnostic {
    /// The file.
    pub file: PathBuf,
    /// 1-based line, where it could be found.
    pub line: Option<usize>,
    /// Dotted field path (`kinematics.joints[2].limits`); empty for the whole file.
    pub path: String,
    /// What is wrong and what was expected.
    pub message: String,
}

impl std::fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
        }
        if !self.path.is_empty() {
            write!(f, ": {}", self.path)?;
        }
        write!(f, ": {}", self.message)
    }
}

fn from_error(file: &Path, e: Error) -> Vec<Diagnostic> {
    match e {
        Error::InvalidFile { file, issues } => issues
            .into_iter()
            .map(|i| Diagnostic {
                file: file.clone(),
                line: i.line,
                path: i.path,
                message: i.message,
            })
            .collect(),
        Error::InputAt { location, message, .. } => vec![Diagnostic {
            file: location.file,
            line: location.line,
            path: String::new(),
            message,
        }],
        other => {
            let message = other.to_string();
            // The diagnostic names the file already.
            let prefix = format!("{}: ", file.display());
            vec![Diagnostic {
                file: file.to_path_buf(),
                line: None,
                path: String::new(),
                message: message.strip_prefix(&prefix).map_or(message.clone(), str::to_string),
            }]
        }
    }
}

/// `/kinematics/joints/2/limits` → `kinematics.joints[2].limits`.
fn pointer_to_path(pointer: &str) -> String {
    let mut out = String::new();
    for seg in pointer.split('/').filter(|s| !s.is_empty()) {
        let seg = seg.replace("~1", "/").replace("~0", "~");
        if seg.chars().all(|c| c.is_ascii_digit()) {
            out.push_str(&format!("[{seg}]"));
        } else {
            if !out.is_empty() {
                out.push('.');
            }
            out.push_str(&seg);
        }
    }
    out
}

/// What checking a file found.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Validation {
    /// Problems: the file is valid when there are none.
    pub problems: Vec<Diagnostic>,
    /// What could not be checked: run-time plugin libraries the user did not allow to load
    /// (their configs are checked against the libraries' schemas only when they load).
    pub not_loaded: Vec<Diagnostic>,
    /// The run-time plugin libraries the file made this run load (and their configs checked).
    pub loaded: Vec<PathBuf>,
    /// What is legal but unlikely (implausible values with their bounds, skipped meshes).
    pub warnings: Vec<String>,
}

/// Checks one robot file (a bare URDF is read and built): syntax and types, then semantics
/// (limits ordered, positive lengths and stiffnesses, links and points that exist, known
/// units), then the JSON Schema.
/// Returns every problem found; an empty list means the file is valid. Every file is read
/// within `limits`.
pub fn validate_file(path: &Path, schema: &Value, limits: InputLimits) -> Vec<Diagnostic> {
    check_file(path, schema, limits).problems
}

/// [`validate_file`], with the plugin libraries that were not loaded apart from the problems.
pub fn check_file(path: &Path, schema: &Value, limits: InputLimits) -> Validation {
    let mut warnings = Vec::new();
    let (diagnostics, inputs) =
        armcomp_core::support::io::recording_reads(|| diagnose_file(path, schema, limits, &mut warnings));
    let (not_loaded, problems) = diagnostics
        .into_iter()
        .partition(|d| d.message.starts_with(armcomp_sdk::NOT_ALLOWED));
    let libraries = armcomp_sdk::loaded_libraries();
    let loaded = inputs.into_iter().filter(|f| libraries.contains(f)).collect();
    Validation {
        problems,
        not_loaded,
        loaded,
        warnings,
    }
}

/// The problems of the file at `path`; a robot that builds adds its warnings to `warnings`.
fn diagnose_file(path: &Path, schema: &Value, limits: InputLimits, warnings: &mut Vec<String>) -> Vec<Diagnostic> {
    if crate::load::is_urdf(path) {
        return match armcomp_urdf::robot_from_urdf(path, limits) {
            Ok(r) => {
                warnings.extend_from_slice(r.warnings());
                Vec::new()
            }
            Err(e) => from_error(path, e),
        };
    }
    let src = match SourceFile::read(path, limits) {
        Ok(s) => s,
        Err(e) => return from_error(path, e),
    };
    // Typed parse first: serde names the field and says what it expected in plain words.
    let file: RobotFile = match src.parse() {
        Ok(f) => f,
        Err(e) => return from_error(path, e),
    };
    // The schema sees the file as parsed (defaults filled in): the text is not parsed twice,
    // which for big files is most of the time validation takes.
    let json = match serde_json::to_value(&file) {
        Ok(v) => v,
        Err(e) => return whole_file(path, format!("cannot be checked against the schema: {e}")),
    };
    // Semantic checks first: they name non-finite numbers plainly, where the schema (which
    // sees them as null) would print the whole plugin table.
    let built = match Robot::from_source(file, &src, limits) {
        Ok(r) => {
            warnings.extend_from_slice(r.warnings());
            Vec::new()
        }
        Err(e) => from_error(path, e),
    };
    if built.iter().any(|d| !d.message.starts_with(armcomp_sdk::NOT_ALLOWED)) {
        return built;
    }
    let validator = match jsonschema::validator_for(schema) {
        Ok(v) => v,
        Err(e) => return whole_file(path, format!("internal error: the robot schema does not compile: {e}")),
    };
    let mut out: Vec<Diagnostic> = validator
        .iter_errors(&json)
        .map(|e| {
            let p = pointer_to_path(e.instance_path().as_str());
            Diagnostic {
                file: path.to_path_buf(),
                line: src.line_of_path(&p),
                path: p,
                message: e.to_string(),
            }
        })
        .collect();
    out.extend(built);
    out
}

/// One problem with the file as a whole (no line, no field).
fn whole_file(path: &Path, message: String) -> Vec<Diagnostic> {
    vec![Diagnostic {
        file: path.to_path_buf(),
        line: None,
        path: String::new(),
        message,
    }]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pointers_become_dotted_paths() {
        assert_eq!(
            pointer_to_path("/kinematics/joints/2/limits"),
            "kinematics.joints[2].limits"
        );
        assert_eq!(pointer_to_path(""), "");
        assert_eq!(pointer_to_path("/a~1b/0"), "a/b[0]");
    }
}
