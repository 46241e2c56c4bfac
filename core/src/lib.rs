//! armcomp-core: the kinematic tree, the plugin traits and the robot file.
//!
//! Everything inside is SI (m, rad, kg, N); units are converted where files are read.
//! The model/workspace split follows Pinocchio: [`KinematicTree`] is immutable, all buffers
//! live in a [`TreeWorkspace`], so forward kinematics and Jacobians allocate nothing.
#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod batch;
pub mod calibrate;
pub mod candidate;
pub mod collision;
pub mod compensate;
pub mod design;
pub mod diagnose;
pub mod error;
pub mod evaluate;
mod frame;
pub mod geom;
pub mod gravity;
pub mod ik;
pub mod interrupt;
pub mod io;
pub mod ladder;
mod lanes;
pub mod least_squares;
pub mod limits;
pub mod mass;
pub mod measurement;
pub mod param;
pub mod perturbation;
pub mod plan;
pub mod plugin;
pub mod point_kinematics;
pub mod point_kinematics_many;
pub mod prior_choice;
pub mod registry;
pub mod residuals;
pub mod robot;
pub mod robot_file;
pub mod role;
pub mod sampling;
pub mod sensor;
pub mod shape;
pub mod simulate;
mod sincos;
pub mod split;
pub mod subtree_loads;
pub mod tree;
pub mod units;
pub mod workspace;

pub use batch::BatchWorkspace;
pub use candidate::{Candidate, CandidateFn, CandidateScope, CandidateTemplate};
pub use collision::{CollisionModel, CollisionWorkspace, Contact};
pub use error::{Error, Issue, Issues, Result};
pub use ik::{
    IkError, IkMethod, IkParams, IkReport, IkTarget, IkWorkspace, LinearOffset, solve_ik, solve_ik_with_offset,
};
pub use param::{ParamInfo, Quantity};
pub use perturbation::Perturbation;
pub use plugin::{
    BuildContext, Chain, ErrorModel, ErrorModelSpec, FittedPredictor, KinematicsSpec, LinkData, Loads, ModelContext,
    PredictorSpec, StaticState, TrainingSet,
};
pub use point_kinematics::{PointKinematics, PointKinematicsWorkspace};
pub use point_kinematics_many::PointKinematicsManyWorkspace;
pub use registry::PluginInfo;
pub use robot::{Conditions, Robot, RobotWorkspace, Station};
pub use robot_file::{RobotFile, SourceFile};
pub use role::Role;
pub use tree::{Body, Coordinate, Coupling, Joint, KinematicTree, Limits, Motion, Point};
pub use units::{AngleUnit, LengthUnit, Units};
pub use workspace::{PointSensitivity, TreeWorkspace};

// Plugin crates implement the typetag traits; they re-export these so they need not depend on
// the macro crates' versions themselves.
pub use schemars;
pub use typetag;
