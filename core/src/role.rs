//! The three roles a plugin can play; a module of its own because errors name them too.

/// What a plugin is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    /// A kinematic convention (`kinematics = { type = ... }`).
    Kinematics,
    /// A physical error model (`[[error_models]]`).
    ErrorModel,
    /// A residual predictor (`[predictor]`).
    Predictor,
}

impl Role {
    /// The robot-file field the role's specs appear in.
    pub fn field(self) -> &'static str {
        match self {
            Role::Kinematics => "kinematics",
            Role::ErrorModel => "error_models",
            Role::Predictor => "predictor",
        }
    }
}

/// The role as messages name it: `kinematics convention`, `error model`, `predictor`.
impl std::fmt::Display for Role {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Role::Kinematics => "kinematics convention",
            Role::ErrorModel => "error model",
            Role::Predictor => "predictor",
        })
    }
}
