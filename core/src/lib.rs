//! armcomp-core: the kinematic tree, the plugin traits and the robot file.
//!
//! Everything inside is SI (m, rad, kg, N); units are converted where files are read.
//! The model/workspace split follows Pinocchio: [`KinematicTree`] is immutable, all buffers
//! live in a [`TreeWorkspace`], so forward kinematics and Jacobians allocate nothing.
#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod algorithms;
pub mod analysis;
pub mod calibrate;
pub mod data;
pub mod error;
pub mod kinematics;
pub mod model;
pub mod plugin;
pub mod robot;
pub mod role;
pub mod support;

pub use algorithms::ik::{
    IkError, IkMethod, IkParams, IkReport, IkTarget, IkWorkspace, LinearOffset, solve_ik, solve_ik_with_offset,
};
pub use error::{Error, Issue, Issues, Result};
pub use kinematics::collision::{CollisionModel, CollisionWorkspace, Contact};
pub use kinematics::point_kinematics::{PointKinematics, PointKinematicsWorkspace};
pub use kinematics::point_kinematics_many::PointKinematicsManyWorkspace;
pub use kinematics::workspace::{PointSensitivity, TreeWorkspace};
pub use model::param::{ParamInfo, Quantity};
pub use model::perturbation::Perturbation;
pub use model::tree::{Body, Coordinate, Coupling, Joint, KinematicTree, Limits, Motion, Point};
pub use model::units::{AngleUnit, LengthUnit, Units};
pub use plugin::{
    BuildContext, Chain, ErrorModel, ErrorModelSpec, FitControl, FittedPredictor, KinematicsSpec, LinkData, Loads,
    ModelContext, PredictorSpec, StaticState, TrainingProgress, TrainingSet,
};
pub use robot::batch::BatchWorkspace;
pub use robot::candidate::{Candidate, CandidateFn, CandidateScope, CandidateTemplate};
pub use robot::registry::PluginInfo;
pub use robot::robot_file::{RobotFile, SourceFile};
pub use robot::{Conditions, Robot, RobotWorkspace, Station};
pub use role::Role;

// Plugin crates implement the typetag traits; they re-export these so they need not depend on
// the macro crates' versions themselves.
pub use schemars;
pub use typetag;
