//! Robot files of the test arms: a 6-axis arm (PUMA-560 geometry) and a 7-joint rock-drill
//! boom (5 revolute + 2 prismatic joints with the deflection paper's joint ranges), each
//! rigid or with gravity error models.

/// The 6-axis arm; `models` is appended (error models in TOML).
pub fn six_axis(models: &str) -> String {
    format!(
        r#"
name = "six-axis"
units = {{ length = "m", angle = "deg" }}
[kinematics]
type = "mdh"
[[kinematics.joints]]
name = "j1"
limits = [-160, 160]
[[kinematics.joints]]
name = "j2"
alpha = -90
limits = [-110, 110]
[[kinematics.joints]]
name = "j3"
a = 0.4318
d = 0.15
limits = [-135, 135]
[[kinematics.joints]]
name = "j4"
alpha = -90
a = 0.0203
d = 0.4318
limits = [-170, 170]
[[kinematics.joints]]
name = "j5"
alpha = 90
limits = [-100, 100]
[[kinematics.joints]]
name = "j6"
alpha = -90
limits = [-180, 180]
[[links]]
name = "j2"
mass = 17.4
com = [0.2, 0, 0.15]
beam = {{ section = {{ shape = "rect_tube", width = 0.12, height = 0.16, wall = 0.004 }}, youngs_modulus = 7.0e10 }}
[[links]]
name = "j3"
mass = 4.8
com = [0.02, 0, 0.2]
beam = {{ section = {{ shape = "tube", outer_diameter = 0.09, wall = 0.003 }}, youngs_modulus = 7.0e10 }}
[[links]]
name = "j6"
mass = 0.5
[[points]]
name = "tool"
link = "j6"
xyz = [0, 0, 0.1]
[payload]
mass = 2.0
{models}
"#
    )
}

/// The 7-joint rock-drill boom; `models` is appended.
pub fn rock_drill(models: &str) -> String {
    format!(
        r#"
name = "rock-drill"
units = {{ length = "m", angle = "deg" }}
[kinematics]
type = "mdh"
[[kinematics.joints]]
name = "j1"
d = 0.3
limits = [-15, 15]
[[kinematics.joints]]
name = "j2"
alpha = 90
a = 0.1
limits = [0, 30]
[[kinematics.joints]]
name = "j3"
kind = "prismatic"
origin = {{ xyz = [1.6, 0, 0], rpy = [0, 90, 0] }}
limits = [0, 0.105]
[[kinematics.joints]]
name = "j4"
alpha = 90
d = 0.15
theta = 90
limits = [0, 60]
[[kinematics.joints]]
name = "j5"
alpha = -90
a = 0.3
limits = [-45, 0]
[[kinematics.joints]]
name = "j6"
alpha = 90
a = 0.1
limits = [-30, 30]
[[kinematics.joints]]
name = "j7"
kind = "prismatic"
alpha = -90
a = 0.2
limits = [0, 0.063]
[[links]]
name = "j2"
mass = 60.0
com = [0.8, 0, 0]
beam = {{ section = {{ shape = "rect_tube", width = 0.1, height = 0.14, wall = 0.005 }}, youngs_modulus = 2.1e11 }}
[[links]]
name = "j3"
mass = 25.0
com = [0, 0, 0.1]
beam = {{ section = {{ shape = "rect_tube", width = 0.08, height = 0.11, wall = 0.004 }}, youngs_modulus = 2.1e11 }}
[[links]]
name = "j5"
mass = 15.0
com = [0.15, 0, 0]
beam = {{ section = {{ shape = "tube", outer_diameter = 0.08, wall = 0.004 }}, youngs_modulus = 2.1e11 }}
[[links]]
name = "j7"
mass = 20.0
com = [0, 0, 0.2]
beam = {{ ei_y = 4.0e5, ei_z = 4.0e5, gj = 3.0e5 }}
[[points]]
name = "tool"
link = "j7"
xyz = [0, 0, 0.45]
[payload]
mass = 10.0
{models}
"#
    )
}

/// Gravity error models for the 6-axis arm.
pub const SIX_AXIS_MODELS: &str = r#"
[[error_models]]
type = "cantilever_deflection"
[[error_models]]
type = "joint_compliance"
compliance = { j2 = 2.0e-6, j3 = 3.0e-6, j5 = 5.0e-6 }
"#;

/// Gravity error models for the rock-drill boom.
pub const ROCK_DRILL_MODELS: &str = r#"
[[error_models]]
type = "cantilever_deflection"
[[error_models]]
type = "joint_compliance"
compliance = { j2 = 1.0e-6, j4 = 4.0e-6, j5 = 6.0e-6 }
"#;
