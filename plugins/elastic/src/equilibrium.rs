//! Static equilibrium of very elastic arms: the loads are evaluated on the deformed arm, which
//! changes the deformation, until it settles (fixed-point iteration).
//!
//! `Robot::forward_into` evaluates every error model once, on the rigid configuration, which is
//! exact to first order. When deflections are large enough to change the loads noticeably,
//! [`solve_equilibrium`] repeats the evaluation on the deformed frames until the deformation
//! stops changing.

use armcomp_core::{Perturbation, Robot, RobotWorkspace, StaticState};

use crate::common::ElasticError;

/// When to stop iterating.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EquilibriumParams {
    /// Most evaluations of the error models (at least 1).
    pub max_iterations: usize,
    /// Largest change of any joint offset or twist component (m or rad) that counts as settled.
    pub tolerance: f64,
}

impl Default for EquilibriumParams {
    fn default() -> Self {
        EquilibriumParams {
            max_iterations: 50,
            tolerance: 1e-12,
        }
    }
}

/// How the iteration went.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EquilibriumReport {
    /// Evaluations of the error models done.
    pub iterations: usize,
    /// Largest change in the last iteration.
    pub change: f64,
}

/// Buffers of the iteration (create once per robot and thread).
#[derive(Debug, Clone)]
pub struct EquilibriumWorkspace {
    previous: Perturbation,
    best: Perturbation,
}

impl EquilibriumWorkspace {
    /// Buffers sized for `robot`.
    pub fn new(robot: &Robot) -> Self {
        EquilibriumWorkspace {
            previous: Perturbation::zeros(robot.tree()),
            best: Perturbation::zeros(robot.tree()),
        }
    }
}

fn max_change(a: &Perturbation, b: &Perturbation) -> f64 {
    let mut m: f64 = 0.0;
    for (x, y) in a.joint_twist.iter().zip(&b.joint_twist) {
        m = m.max((x - y).amax());
    }
    for (x, y) in a.point_twist.iter().zip(&b.point_twist) {
        m = m.max((x - y).amax());
    }
    for (x, y) in a.joint_offset.iter().zip(&b.joint_offset) {
        m = m.max((x - y).abs());
    }
    m
}

/// Evaluates the full model of `robot` at `q` with the loads taken on the deformed arm.
///
/// On success `ws.frames` holds the deformed arm in equilibrium and `ws.perturbation` its
/// deformation. When it does not settle within `opts.max_iterations` (or the deformation stops
/// being finite), `ws` holds the iterate that changed least and the error says by how much.
/// No allocation after the workspaces are made.
pub fn solve_equilibrium(
    robot: &Robot,
    q: &[f64],
    temperature: Option<f64>,
    opts: &EquilibriumParams,
    ws: &mut RobotWorkspace,
    eq: &mut EquilibriumWorkspace,
) -> Result<EquilibriumReport, ElasticError> {
    let tree = robot.tree();
    tree.check_q(q)?;
    tree.forward_into(q, &mut ws.rigid);
    ws.frames.clone_from(&ws.rigid);
    eq.previous.clear();
    let mut best = f64::INFINITY;
    let mut change = f64::INFINITY;
    for it in 1..=opts.max_iterations.max(1) {
        ws.perturbation.clear();
        // The loads as load-adjusting models leave them (a payload's corrected mass, a tilted
        // gravity), with no per-measurement payload.
        let (own_mass, gravity) = robot.loads_into(
            armcomp_core::Conditions {
                temperature,
                ..Default::default()
            },
            tree,
            &ws.rigid,
            robot.error_values(),
            &mut ws.mass,
        );
        let mass = if own_mass { robot.mass() } else { &ws.mass };
        ws.loads.update(tree, &ws.frames, mass);
        let state = StaticState {
            q,
            tree,
            frames: &ws.frames,
            mass,
            loads: &ws.loads,
            gravity,
            temperature,
            sensors: Default::default(),
        };
        for (m, v) in robot.error_models().iter().zip(robot.error_values()) {
            m.perturb(&state, v, &mut ws.perturbation);
        }
        change = max_change(&ws.perturbation, &eq.previous);
        if !change.is_finite() {
            break;
        }
        if change < best {
            best = change;
            eq.best.clone_from(&ws.perturbation);
        }
        tree.forward_perturbed_into(q, &ws.perturbation, &mut ws.frames);
        if change <= opts.tolerance {
            return Ok(EquilibriumReport { iterations: it, change });
        }
        eq.previous.clone_from(&ws.perturbation);
        if it == opts.max_iterations.max(1) {
            break;
        }
    }
    let iterations = opts.max_iterations.max(1);
    if best.is_finite() {
        ws.perturbation.clone_from(&eq.best);
        tree.forward_perturbed_into(q, &ws.perturbation, &mut ws.frames);
    }
    Err(ElasticError::NotConverged {
        iterations,
        change: if best.is_finite() { best } else { change },
    })
}
