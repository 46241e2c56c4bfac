//! The built-in robots, compiled into the binary so `armcomp demo` runs from anywhere.

use std::path::Path;

use armcomp_core::robot::robot_file::{Format, SourceFile};
use armcomp_core::support::io::InputLimits;
use armcomp_core::{Error, Result, Robot};

/// A built-in robot file: its name, its path in the repository and its text.
pub struct Twin {
    /// Short name used on the command line.
    pub name: &'static str,
    /// Path in the repository (used in messages).
    pub path: &'static str,
    /// The robot file.
    pub text: &'static str,
}

/// Every robot file shipped in `robots/`.
pub const TWINS: &[Twin] = &[
    Twin {
        name: "rock-drill",
        path: "robots/rock-drill.toml",
        text: include_str!("../../robots/rock-drill.toml"),
    },
    Twin {
        name: "rock-drill-deflection",
        path: "robots/rock-drill-deflection.toml",
        text: include_str!("../../robots/rock-drill-deflection.toml"),
    },
    Twin {
        name: "rock-drill-truth",
        path: "robots/rock-drill-truth.toml",
        text: include_str!("../../robots/rock-drill-truth.toml"),
    },
    Twin {
        name: "industrial",
        path: "robots/industrial-6dof.toml",
        text: include_str!("../../robots/industrial-6dof.toml"),
    },
    Twin {
        name: "industrial-truth",
        path: "robots/industrial-6dof-truth.toml",
        text: include_str!("../../robots/industrial-6dof-truth.toml"),
    },
    Twin {
        name: "industrial-dh",
        path: "robots/industrial-6dof-dh.toml",
        text: include_str!("../../robots/industrial-6dof-dh.toml"),
    },
    Twin {
        name: "industrial-poe",
        path: "robots/industrial-6dof-poe.toml",
        text: include_str!("../../robots/industrial-6dof-poe.toml"),
    },
    Twin {
        name: "agile-justin",
        path: "robots/agile-justin.toml",
        text: include_str!("../../robots/agile-justin.toml"),
    },
];

impl Twin {
    /// Finds a built-in robot by its short name.
    pub fn get(name: &str) -> Option<&'static Twin> {
        TWINS.iter().find(|t| t.name == name)
    }

    /// Builds the built-in robot `name`.
    pub fn build(name: &str) -> Result<Robot> {
        let twin = Twin::get(name).ok_or_else(|| Error::InvalidArgument {
            what: "built-in robot".into(),
            reason: format!(
                "there is none named `{name}`; there are {}",
                TWINS.iter().map(|t| t.name).collect::<Vec<_>>().join(", ")
            ),
        })?;
        twin.robot()
    }

    /// Builds the robot.
    pub fn robot(&self) -> Result<Robot> {
        let src = SourceFile {
            path: Path::new(self.path).to_path_buf(),
            text: self.text.to_string(),
            format: Format::Toml,
        };
        let file = src.parse()?;
        Robot::from_source(file, &src, InputLimits::default())
    }
}
