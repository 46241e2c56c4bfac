//! Rust errors as the package's Python exceptions (defined in `armcomp/_errors.py`): bad input
//! (files, arguments, plugin names and libraries) is `armcomp.InputError` with `file`, `line`
//! and `field` when known, an interruption is `KeyboardInterrupt`, a file that cannot be
//! written (or read by the system) `OSError`, a solver that gave up or data without a unique
//! answer `armcomp.ArmcompError`.

use std::path::Path;

use armcomp_core::{Error, IkError};
use pyo3::exceptions::{PyKeyboardInterrupt, PyOSError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// Hands `messages` to Python's `warnings` as `UserWarning`s.
pub fn warn_all(py: Python<'_>, messages: &[String]) -> PyResult<()> {
    for w in messages {
        let message = std::ffi::CString::new(w.replace('\0', " ")).expect("no NUL left");
        PyErr::warn(py, &py.get_type::<pyo3::exceptions::PyUserWarning>(), &message, 1)?;
    }
    Ok(())
}

/// An `armcomp.InputError` with its message and location.
pub fn input_error(message: &str, file: Option<&Path>, line: Option<usize>, field: Option<&str>) -> PyErr {
    Python::attach(|py| {
        let build = || -> PyResult<PyErr> {
            let class = py.import("armcomp._errors")?.getattr("InputError")?;
            let kwargs = PyDict::new(py);
            kwargs.set_item("file", file.map(|f| f.display().to_string()))?;
            kwargs.set_item("line", line)?;
            kwargs.set_item("field", field)?;
            Ok(PyErr::from_value(class.call((message,), Some(&kwargs))?))
        };
        build().unwrap_or_else(|e| e)
    })
}

/// An `armcomp.ArmcompError`: a failure that is not the input's fault (a solver that did not
/// converge, data that leave no unique answer).
fn armcomp_error(message: &str) -> PyErr {
    Python::attach(|py| {
        let build = || -> PyResult<PyErr> {
            let class = py.import("armcomp._errors")?.getattr("ArmcompError")?;
            Ok(PyErr::from_value(class.call1((message,))?))
        };
        build().unwrap_or_else(|e| e)
    })
}

/// The operating system's errno, or for armcomp's own refusals the nearest one by their kind:
/// a missing folder `ENOENT`, a read-only or foreign file `EACCES`, a file where a folder was
/// meant `ENOTDIR`, any other refusal (an input, a link, a special file as output) `EINVAL`.
fn os_errno(kind: std::io::ErrorKind, os_code: Option<i32>) -> i32 {
    use std::io::ErrorKind;
    const ENOENT: i32 = 2;
    const EACCES: i32 = 13;
    const ENOTDIR: i32 = 20;
    const EINVAL: i32 = 22;
    os_code.unwrap_or(match kind {
        ErrorKind::NotFound => ENOENT,
        ErrorKind::PermissionDenied | ErrorKind::ReadOnlyFilesystem => EACCES,
        ErrorKind::NotADirectory => ENOTDIR,
        _ => EINVAL,
    })
}

/// The Python exception for a core error; `context` (the message of an error wrapping it)
/// replaces the message.
pub fn core_error(e: &Error, context: Option<&str>) -> PyErr {
    let message = context.map_or_else(|| e.to_string(), str::to_string);
    match e {
        Error::Interrupted => PyKeyboardInterrupt::new_err(message),
        Error::Io {
            path,
            kind,
            os_code,
            message: reason,
        } => {
            // As Python's own file errors: `errno`, the reason as `strerror`, and `filename`,
            // which `str()` shows as `[Errno N] reason: 'path'`.
            PyOSError::new_err((os_errno(*kind, *os_code), reason.clone(), path.display().to_string()))
        }
        Error::InvalidFile { file, issues } => {
            let first = issues.first();
            let field = first.map(|i| i.path.as_str()).filter(|p| !p.is_empty());
            input_error(&message, Some(file), first.and_then(|i| i.line), field)
        }
        Error::InvalidModel(issues) => {
            let field = issues.first().map(|i| i.path.as_str()).filter(|p| !p.is_empty());
            input_error(&message, None, None, field)
        }
        Error::InputAt { location, column, .. } => {
            input_error(&message, Some(&location.file), location.line, column.as_deref())
        }
        Error::Dimension { what, .. } | Error::InvalidArgument { what, .. } | Error::TooLarge { what, .. } => {
            input_error(&message, None, None, Some(what))
        }
        Error::UnknownPlugin { role, .. } => input_error(&message, None, None, Some(role.field())),
        Error::AbiMismatch { library, .. } | Error::PluginNotAllowed { library } | Error::Plugin { library, .. } => {
            input_error(&message, Some(library), None, None)
        }
        // Not converged, degenerate, and kinds added later: armcomp's own error.
        _ => armcomp_error(&message),
    }
}

/// An error's message with those of its sources, `: `-separated (as the command line prints it).
fn chain(e: &dyn std::error::Error) -> String {
    let mut message = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        message = format!("{message}: {s}");
        source = s.source();
    }
    message
}

/// The Python exception for an error of the operations, with the whole chain as the message:
/// bad start configurations and locked joints are input errors of the arguments `start` and
/// `lock`, a target the solver could not reach is armcomp's own error.
pub fn api_error(e: &armcomp_api::Error) -> PyErr {
    use armcomp_api::Error as Api;
    let message = chain(e);
    match e {
        Api::Core(core) => core_error(core, None),
        Api::StartConfiguration { .. } | Api::StartCount { .. } => input_error(&message, None, None, Some("start")),
        Api::LockedJoint { .. } => input_error(&message, None, None, Some("lock")),
        Api::Target { source, .. } => match source.as_ref() {
            IkError::Input(core) => core_error(core, Some(&message)),
            _ => armcomp_error(&message),
        },
        _ => armcomp_error(&message),
    }
}

/// [`core_error`] for an error reading `path`: a message about the file as a whole (`path:
/// does not exist`) names it as the `file` too.
pub fn file_error(e: &Error, path: &Path) -> PyErr {
    let err = core_error(e, None);
    Python::attach(|py| {
        let value = err.value(py);
        let unnamed = value.getattr("file").is_ok_and(|f| f.is_none());
        if unnamed && e.to_string().starts_with(&format!("{}:", path.display())) {
            let _ = value.setattr("file", path.display().to_string());
        }
    });
    err
}

/// `Result` of the core as a Python result.
pub trait IntoPy<T> {
    /// Maps the error to its Python exception.
    fn py(self) -> PyResult<T>;
}

impl<T> IntoPy<T> for armcomp_core::Result<T> {
    fn py(self) -> PyResult<T> {
        self.map_err(|e| core_error(&e, None))
    }
}

impl<T> IntoPy<T> for armcomp_api::Result<T> {
    fn py(self) -> PyResult<T> {
        self.map_err(|e| api_error(&e))
    }
}
