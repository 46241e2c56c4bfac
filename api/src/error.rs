//! The errors of the operations: core's, and the failures the operations have of their own,
//! each with the values a caller may act on. A variant that wraps a core error says only what
//! it adds; the core error is its [`source`](std::error::Error::source), so a caller printing
//! the whole chain (`{:#}` of an `anyhow::Error`) reads `start configuration 2: <core's message>`.

use armcomp_core::IkError;
use armcomp_core::data::measurement::listed;

/// An error of the operations. New kinds may be added, so a `match` needs a catch-all arm.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// An error of the core library or of a plugin (bad input files, solvers that gave up,
    /// interruptions).
    #[error(transparent)]
    Core(#[from] armcomp_core::Error),
    /// A start configuration of compensation is not a configuration of the robot.
    #[error("start configuration {index}")]
    StartConfiguration {
        /// Which, counted from 1.
        index: usize,
        /// What is wrong with it.
        source: armcomp_core::Error,
    },
    /// The start configurations are neither one for all targets nor one per target.
    #[error("{starts} start configurations for {targets} targets; give one for all or one per target")]
    StartCount {
        /// How many were given.
        starts: usize,
        /// How many targets there are.
        targets: usize,
    },
    /// A joint asked to be locked cannot be.
    #[error("locked joint `{name}` {reason}")]
    LockedJoint {
        /// The name asked for.
        name: String,
        /// Why it cannot be locked.
        reason: LockReason,
    },
    /// A target could not be compensated.
    #[error("{target}")]
    Target {
        /// The target, as the caller describes it (`targets.csv:7`, `target 3`).
        target: String,
        /// Why: out of reach (with the closest configuration found), or a bad request (boxed:
        /// the closest configuration would make every result of the operations large).
        source: Box<IkError>,
    },
    /// An exported URDF, read back, does not put the links and points where the model does.
    #[error(
        "the exported URDF, read back, puts a link or point {deviation:.3e} m from the model over {configurations} configurations (tolerance {tolerance:.0e} m); nothing was written"
    )]
    ReloadMismatch {
        /// The largest distance (m).
        deviation: f64,
        /// What it may be (m).
        tolerance: f64,
        /// How many configurations were compared.
        configurations: usize,
    },
}

/// Why a joint cannot be locked.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LockReason {
    /// It is a mimic joint: the coordinates it follows are what to lock.
    Mimic {
        /// The coordinates that drive it.
        follows: Vec<String>,
    },
    /// It is a fixed joint.
    Fixed,
    /// The robot has no joint of that name.
    Unknown {
        /// The robot's name.
        robot: String,
        /// Its coordinates, which may be locked.
        joints: Vec<String>,
    },
}

impl std::fmt::Display for LockReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let names = |n: &[String]| listed(&n.iter().map(String::as_str).collect::<Vec<_>>());
        match self {
            LockReason::Mimic { follows } => {
                write!(f, "is a mimic joint; lock the joint it follows: {}", names(follows))
            }
            LockReason::Fixed => f.write_str("is a fixed joint, which never moves"),
            LockReason::Unknown { robot, joints } => {
                write!(f, "is not a joint of `{robot}`; its joints are {}", names(joints))
            }
        }
    }
}

/// Result with the operations' [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
