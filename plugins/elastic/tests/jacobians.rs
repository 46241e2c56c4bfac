//! Every plugin's parameter Jacobian at the tool: the analytic chain rule (the model's
//! derivative mapped to the tool by Eq. 5) against central finite differences of the composed
//! forward kinematics.

use crate::common::{perturbation_of, robot};
use armcomp_core::TreeWorkspace;
use armcomp_elastic::tool_differential_world;
use nalgebra::Vector6;

const ARM: &str = r#"
name = "jac"
gravity = [0.4, -0.9, -9.7]
[kinematics]
type = "mdh"
[[kinematics.joints]]
name = "j1"
d = 0.2
[[kinematics.joints]]
name = "j2"
alpha = 1.5707963267948966
a = 0.1
[[kinematics.joints]]
name = "j3"
kind = "prismatic"
a = 0.9
alpha = -1.5707963267948966
[[kinematics.joints]]
name = "j4"
alpha = 1.5707963267948966
a = 0.05
d = 0.3
[[links]]
name = "j2"
mass = 30.0
com = [0.45, 0, 0]
beam = { ei_y = 4.0e6, ei_z = 6.0e6, gj = 3.0e6 }
[[links]]
name = "j3"
mass = 10.0
com = [0, 0, 0.1]
beam = { ei_y = 2.0e6, ei_z = 2.5e6, gj = 1.0e6 }
[[links]]
name = "j4"
mass = 5.0
com = [0.1, 0.02, 0.1]
beam = { ei_y = 1.0e6, ei_z = 1.5e6, gj = 0.8e6 }
[[points]]
name = "tool"
link = "j4"
xyz = [0.1, 0.05, 0.25]
[payload]
mass = 4.0
[[error_models]]
type = "cantilever_deflection"
[[error_models]]
type = "joint_compliance"
compliance = { j2 = 1.0e-6, j3 = 2.0e-7, j4 = 3.0e-6 }
[[error_models]]
type = "lateral_compliance"
compliance = { j2 = [1.0e-6, 2.0e-6], j4 = [3.0e-6, 1.0e-6] }
[[error_models]]
type = "geometric_offsets"
[[error_models]]
type = "backlash"
backlash = { j2 = 0.001, j4 = 0.002 }
smoothing = 50.0
[[error_models]]
type = "encoder_eccentricity"
eccentricity = { j1 = [0.001, -0.002], j4 = [0.0005, 0.001] }
[[error_models]]
type = "thermal_growth"
coefficient = 1.2e-5
[[error_models]]
type = "base_tilt"
[[error_models]]
type = "payload_mass_error"
mass = 1.0
[[error_models]]
type = "transmission_scale"
scale = { j1 = 0.001, j3 = -0.002 }
"#;

/// Checks d(tool)/d(param) for every parameter of model `m`. Models linear in their
/// parameters: the derivative of the deformation is the deformation at a unit parameter, taken
/// at zero. The cantilever (deflection ∝ 1/scale) is checked at scale 1, where the derivative
/// of the deformation is minus the deformation; its beams bend little (1e-5 rad), so Eq. 5 holds
/// to that relative order. Position and orientation of the tool are both compared.
fn check_model(m: usize, q: &[f64], temperature: Option<f64>) {
    let r = robot(ARM);
    let tool = r.tool();
    let model = &r.error_models()[m];
    let n = model.params().len();
    assert!(n > 0);
    let nonlinear = model.params()[0].name.starts_with("cantilever.");
    let base: Vec<f64> = if nonlinear { vec![1.0; n] } else { vec![0.0; n] };
    for k in 0..n {
        let analytic = if nonlinear {
            let (pert, rigid) = perturbation_of(&r, m, &base, q, temperature);
            // Only the links whose scale is k contribute: isolate them by differencing.
            let mut other = base.clone();
            other[k] = 2.0;
            let (pert2, _) = perturbation_of(&r, m, &other, q, temperature);
            // d/ds (1/s)·D at s = 1 is −D_k, and D_k = 2·(D(1) − D(2)).
            let (a, aw) = tool_differential_world(r.tree(), &rigid, &pert, tool);
            let (b, bw) = tool_differential_world(r.tree(), &rigid, &pert2, tool);
            let (d, w) = (-(a - b) * 2.0, -(aw - bw) * 2.0);
            Vector6::new(d.x, d.y, d.z, w.x, w.y, w.z)
        } else {
            let mut unit = base.clone();
            unit[k] = 1.0;
            let (pert, rigid) = perturbation_of(&r, m, &unit, q, temperature);
            let (d, w) = tool_differential_world(r.tree(), &rigid, &pert, tool);
            Vector6::new(d.x, d.y, d.z, w.x, w.y, w.z)
        };
        let name = &model.params()[k].name;
        let h = if nonlinear {
            1e-3
        } else if analytic.norm() > 0.0 {
            1e-7 / analytic.norm()
        } else {
            1e-3
        };
        let mut plus = base.clone();
        plus[k] += h;
        let mut minus = base.clone();
        minus[k] -= h;
        let (pp, rp) = pose_with(&r, m, &plus, q, temperature, tool);
        let (pm, rm) = pose_with(&r, m, &minus, q, temperature, tool);
        let dp = (pp - pm) / (2.0 * h);
        let dr = (rp * rm.inverse()).scaled_axis() / (2.0 * h);
        let fd = Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z);
        if analytic.norm() < 1e-15 {
            // No effect in this configuration (e.g. no torsion on the last link): none measured.
            assert!(fd.norm() < 1e-9, "{name}: analytic 0, finite differences {fd}");
            continue;
        }
        let err = (fd - analytic).norm() / analytic.norm();
        let tol = if nonlinear { 1e-4 } else { 1e-6 };
        assert!(
            err < tol,
            "{name}: analytic {analytic} vs finite differences {fd} (relative {err:e})"
        );
    }
}

/// Tool position and orientation with model `m` alone at `values`.
fn pose_with(
    r: &armcomp_core::Robot,
    m: usize,
    values: &[f64],
    q: &[f64],
    temperature: Option<f64>,
    p: usize,
) -> (nalgebra::Vector3<f64>, nalgebra::UnitQuaternion<f64>) {
    let (pert, _) = perturbation_of(r, m, values, q, temperature);
    let mut ws = TreeWorkspace::new(r.tree());
    r.tree().forward_perturbed_into(q, &pert, &mut ws);
    (ws.point[p].translation.vector, ws.point[p].rotation)
}

const Q: [f64; 4] = [0.4, 0.6, 0.3, -0.8];

#[test]
fn cantilever() {
    check_model(0, &Q, None);
}
#[test]
fn joint_compliance() {
    check_model(1, &Q, None);
}
#[test]
fn lateral_compliance() {
    check_model(2, &Q, None);
}
#[test]
fn geometric_offsets() {
    check_model(3, &Q, None);
}
#[test]
fn backlash() {
    check_model(4, &Q, None);
}
#[test]
fn encoder_eccentricity() {
    check_model(5, &Q, None);
}
#[test]
fn thermal_growth() {
    check_model(6, &Q, Some(35.0));
}
#[test]
fn base_tilt() {
    check_model(7, &Q, None);
}
/// The payload error and the base tilt change the loads every elastic model sees: the arm
/// with them is the arm whose file declares the corrected payload, or gravity turned by the
/// tilt (and the base turned with it), computed by the other models alone.
#[test]
fn load_adjusting_models_are_the_loads_every_elastic_model_sees() {
    let keep = |drop: &[&str], replace: &[(&str, &str)]| {
        let mut text = ARM.to_string();
        for (from, to) in replace {
            assert!(text.contains(from), "{from}");
            text = text.replacen(from, to, 1);
        }
        for block in drop {
            assert!(text.contains(block), "{block}");
            text = text.replacen(block, "", 1);
        }
        robot(&text)
    };
    let payload_error = "[[error_models]]\ntype = \"payload_mass_error\"\nmass = 1.0\n";
    let tilt = "[[error_models]]\ntype = \"base_tilt\"\n";
    let tool = |r: &armcomp_core::Robot| r.forward(&Q).unwrap().point[r.tool()].translation.vector;
    // (1 + 0.25) · 4 kg + 1 kg = 6 kg.
    let with_error = keep(&[tilt], &[("mass = 1.0\n", "mass = 1.0\nscale = 0.25\n")]);
    let declared_six = keep(
        &[tilt, payload_error],
        &[("[payload]\nmass = 4.0", "[payload]\nmass = 6.0")],
    );
    let declared_four = keep(&[tilt, payload_error], &[]);
    let (a, b, c) = (tool(&with_error), tool(&declared_six), tool(&declared_four));
    assert!((a - b).norm() < 1e-12, "{a} vs {b}");
    assert!((a - c).norm() > 1e-6, "the extra 2 kg bend the arm: {a} vs {c}");
    // A tilt of 2° and -1°: gravity turned back by it in the base frame, the base turned by it.
    let (tx, ty) = (2f64.to_radians(), -1f64.to_radians());
    let turn = nalgebra::UnitQuaternion::from_scaled_axis(nalgebra::Vector3::new(tx, ty, 0.0));
    let g = turn.inverse_transform_vector(&nalgebra::Vector3::new(0.4, -0.9, -9.7));
    let tilted = keep(
        &[payload_error],
        &[(
            "type = \"base_tilt\"\n",
            &format!("type = \"base_tilt\"\ntilt = [{tx}, {ty}]\n"),
        )],
    );
    let by_hand = keep(
        &[payload_error, tilt],
        &[
            (
                "gravity = [0.4, -0.9, -9.7]",
                &format!("gravity = [{}, {}, {}]", g.x, g.y, g.z),
            ),
            (
                "type = \"geometric_offsets\"\n",
                &format!("type = \"geometric_offsets\"\nbase = [0, 0, 0, {tx}, {ty}, 0]\n"),
            ),
        ],
    );
    let level = keep(&[payload_error], &[]);
    let (a, b, c) = (tool(&tilted), tool(&by_hand), tool(&level));
    assert!((a - b).norm() < 1e-12, "{a} vs {b}");
    assert!((a - c).norm() > 1e-4, "{a} vs {c}");
}
#[test]
fn transmission_scale() {
    check_model(9, &Q, None);
}

#[test]
fn every_plugin_is_registered_with_a_schema() {
    let plugins = armcomp_elastic::plugins();
    let r = robot(ARM);
    for t in r.error_model_types() {
        assert!(plugins.iter().any(|p| p.type_name == t), "{t} not in plugins()");
    }
    let mut g = schemars::SchemaGenerator::default();
    for p in &plugins {
        assert!(!p.doc.is_empty(), "{} has no doc", p.type_name);
        // Geometric offsets duplicate what the base frame and marker offsets already identify,
        // so diagnosis does not try them; every physical effect is a candidate that can place
        // itself on a robot.
        let candidate = p.type_name != "geometric_offsets";
        assert_eq!(p.diagnosis_candidate, candidate, "{}", p.type_name);
        assert_eq!(p.candidates.is_some(), candidate, "{}", p.type_name);
        let s = (p.schema)(&mut g);
        assert!(s.as_object().is_some_and(|o| !o.is_empty()), "{}", p.type_name);
    }
}

/// `KinematicTree::point_perturbation_effect`, which the calibration's exact Jacobian uses:
/// at the rigid frames it is Eq. 5's displacement (an independent formula through adjoints);
/// at a deformed configuration it is the derivative of the perturbed forward kinematics along
/// a change of the deformation, by central differences.
#[test]
fn point_perturbation_effect_is_eq5_and_the_derivative_of_perturbed_fk() {
    let r = robot(ARM);
    let tool = r.tool();
    let tree = r.tree();
    // The whole deformation of every model at its file values, and a change made of model 1
    // (joint offsets) and model 2 (joint twists) at other values, plus a point twist.
    let all = |values: &dyn Fn(usize) -> Vec<f64>| {
        let mut total = armcomp_core::Perturbation::zeros(tree);
        for m in 0..r.error_models().len() {
            let (p, _) = perturbation_of(&r, m, &values(m), &Q, Some(35.0));
            add_scaled(&mut total, &p, 1.0);
        }
        total
    };
    let defaults = r.error_values();
    let base = all(&|m| defaults[m].clone());
    let mut change = all(&|m| match m {
        1 | 2 => defaults[m].iter().map(|v| 3.0 * v + 1e-6).collect(),
        _ => vec![0.0; defaults[m].len()],
    });
    change.point_twist[tool] = Vector6::new(1e-4, -2e-4, 3e-4, 2e-3, -1e-3, 4e-3);
    assert!(!base.is_zero() && !change.is_zero());

    // Rigid frames: Eq. 5.
    let (_, rigid) = perturbation_of(&r, 0, &defaults[0], &Q, None);
    let (eq5, _) = tool_differential_world(tree, &rigid, &change, tool);
    let none = armcomp_core::Perturbation::zeros(tree);
    let effect = tree.point_perturbation_effect(&rigid, &none, tool, &change);
    assert!((effect - eq5).norm() <= 1e-12 * eq5.norm(), "{effect} vs Eq. 5 {eq5}");

    // Deformed frames: central differences of the perturbed forward kinematics.
    let mut ws = TreeWorkspace::new(tree);
    tree.forward_perturbed_into(&Q, &base, &mut ws);
    let effect = tree.point_perturbation_effect(&ws, &base, tool, &change);
    let at = |s: f64| {
        let mut p = base.clone();
        add_scaled(&mut p, &change, s);
        let mut w = TreeWorkspace::new(tree);
        tree.forward_perturbed_into(&Q, &p, &mut w);
        w.point[tool].translation.vector
    };
    let h = 1e-3;
    let fd = (at(h) - at(-h)) / (2.0 * h);
    let size = base.joint_twist.iter().map(|t| t.norm()).fold(0.0, f64::max);
    assert!(size > 1e-5, "deformation size {size}");
    let err = (effect - fd).norm() / fd.norm();
    assert!(err < 1e-7, "{effect} vs finite differences {fd} (relative {err:e})");
    // Not the rigid-frame value: the deformed frames matter at this tolerance.
    let rigid_effect = tree.point_perturbation_effect(&rigid, &none, tool, &change);
    assert!((rigid_effect - fd).norm() > 1e2 * (effect - fd).norm());
}

/// `a += s · b`, entry by entry.
fn add_scaled(a: &mut armcomp_core::Perturbation, b: &armcomp_core::Perturbation, s: f64) {
    a.joint_twist
        .iter_mut()
        .zip(&b.joint_twist)
        .for_each(|(x, y)| *x += y * s);
    a.joint_offset
        .iter_mut()
        .zip(&b.joint_offset)
        .for_each(|(x, y)| *x += y * s);
    a.point_twist
        .iter_mut()
        .zip(&b.point_twist)
        .for_each(|(x, y)| *x += y * s);
}

/// The subtree loads of one backward pass against the weight of each subtree summed body by
/// body (bodies found through the tree's support lists, the payload at its body), about an
/// arbitrary point, at a configuration away from zero.
#[test]
fn subtree_loads_are_the_sums_over_each_subtree() {
    let r = robot(ARM);
    let tree = r.tree();
    let mut frames = TreeWorkspace::new(tree);
    tree.forward_into(&Q, &mut frames);
    let loads = armcomp_core::kinematics::subtree_loads::SubtreeLoads::of(tree, &frames, r.mass());
    let g = r.gravity();
    let about = nalgebra::Vector3::new(0.3, -0.2, 0.5);
    let payload = r.mass().payload.as_ref().expect("the arm carries a payload");
    for c in 0..tree.bodies().len() {
        let in_subtree = |k: usize| k == c || c == 0 || tree.support(k).contains(&(c - 1));
        let (mut force, mut moment) = (nalgebra::Vector3::zeros(), nalgebra::Vector3::zeros());
        let mut add = |body: usize, mass: f64, com: &nalgebra::Vector3<f64>| {
            let at = frames.body[body].transform_point(&(*com).into()).coords;
            force += g * mass;
            moment += (at - about).cross(&(g * mass));
        };
        for (k, b) in r.mass().bodies.iter().enumerate().filter(|(k, _)| in_subtree(*k)) {
            add(k, b.mass, &b.com);
        }
        if in_subtree(payload.body) {
            add(payload.body, payload.mass, &payload.com);
        }
        let (f, m) = loads.wrench(c, &g, &about);
        assert!(
            (f - force).norm() <= 1e-12 * force.norm().max(1.0),
            "body {c}: {f} vs {force}"
        );
        assert!(
            (m - moment).norm() <= 1e-12 * moment.norm().max(1.0),
            "body {c}: {m} vs {moment}"
        );
    }
    assert!(loads.mass(0) > payload.mass);
}

/// The deformed evaluation that copies the joints before the first perturbed one from the
/// rigid evaluation gives the same bits as the full one, for deformations starting at each
/// joint of the arm.
#[test]
fn perturbed_fk_from_the_rigid_frames_is_the_full_evaluation() {
    let r = robot(ARM);
    let tree = r.tree();
    let mut rigid = TreeWorkspace::new(tree);
    tree.forward_into(&Q, &mut rigid);
    let (mut full, mut from_rigid) = (TreeWorkspace::new(tree), TreeWorkspace::new(tree));
    for first in 0..tree.joints().len() {
        let mut pert = armcomp_core::Perturbation::zeros(tree);
        for j in first..tree.joints().len() {
            pert.joint_twist[j] = Vector6::new(1e-4, -2e-4, 3e-4, 1e-3, 2e-3, -1e-3) * (j + 1) as f64;
            pert.joint_offset[j] = 1e-3 * j as f64;
        }
        pert.point_twist[r.tool()] = Vector6::new(0.0, 1e-4, 0.0, 0.0, 0.0, 2e-3);
        tree.forward_perturbed_into(&Q, &pert, &mut full);
        // Whatever the workspace held before (another configuration) must not survive.
        tree.forward_into(&[0.1, -0.2, 0.05, 0.3], &mut from_rigid);
        tree.forward_perturbed_from_rigid_into(&Q, &pert, &rigid, &mut from_rigid);
        assert_eq!(from_rigid.body, full.body, "first perturbed joint {first}");
        assert_eq!(from_rigid.joint_frame, full.joint_frame);
        assert_eq!(from_rigid.point, full.point);
        assert_eq!(from_rigid.joint_value, full.joint_value);
        assert_ne!(full.point[r.tool()], rigid.point[r.tool()]);
    }
}

/// The deformation of a tree whose geometry is stepped at one joint, evaluated from the
/// unstepped tree's rigid frames and motions, is the full evaluation's, bit for bit, for a step
/// of every chain parameter.
#[test]
fn deformation_of_a_restepped_tree_is_the_full_evaluation() {
    let r = robot(ARM);
    let conditions = armcomp_core::Conditions::default();
    let mut base = r.workspace();
    r.deformation_into(r.tree(), r.error_values(), &Q, conditions, &mut base);
    let (mut full, mut restepped) = (r.workspace(), r.workspace());
    let mut tested_after_the_first = false;
    for k in 0..r.chain_values().len() {
        let mut values = r.chain_values().to_vec();
        values[k] += 1e-3;
        let tree = r.tree_for(&values).expect("stepped tree");
        let stepped: Vec<usize> = (0..tree.joints().len())
            .filter(|&j| tree.joints()[j].placement != r.tree().joints()[j].placement)
            .collect();
        tested_after_the_first |= stepped.first().is_some_and(|&j| j > 0);
        r.deformation_into(&tree, r.error_values(), &Q, conditions, &mut full);
        // Whatever the workspace held before (another configuration) must not survive.
        r.deformation_into(
            r.tree(),
            r.error_values(),
            &[0.1, -0.2, 0.05, 0.3],
            conditions,
            &mut restepped,
        );
        r.deformation_restepped_into(
            &tree,
            r.error_values(),
            &Q,
            conditions,
            &base.rigid,
            &stepped,
            &mut restepped,
        );
        assert_eq!(restepped.rigid.body, full.rigid.body, "parameter {k}");
        assert_eq!(restepped.rigid.joint_frame, full.rigid.joint_frame, "parameter {k}");
        assert_eq!(restepped.rigid.point, full.rigid.point, "parameter {k}");
        assert_eq!(restepped.perturbation, full.perturbation, "parameter {k}");
        assert_ne!(
            full.perturbation, base.perturbation,
            "parameter {k} changes the deformation"
        );
    }
    assert!(tested_after_the_first);
}

/// A model that calls itself inactive at zero values deforms nothing there, in any
/// configuration; the compliance models are the ones that do, and not at their own values.
#[test]
fn inactive_models_deform_nothing() {
    let r = robot(ARM);
    let mut inactive = Vec::new();
    for (m, model) in r.error_models().iter().enumerate() {
        let zeros = vec![0.0; model.params().len()];
        let own = &r.error_values()[m];
        assert!(!model.is_inactive(own) || own.iter().all(|&v| v == 0.0), "model {m}");
        if !model.is_inactive(&zeros) {
            continue;
        }
        inactive.push(m);
        for q in [[0.4, 0.6, 0.3, -0.8], [-1.0, 0.1, 0.05, 2.0]] {
            let (pert, _) = perturbation_of(&r, m, &zeros, &q, Some(60.0));
            assert_eq!(pert, armcomp_core::Perturbation::zeros(r.tree()), "model {m} at {q:?}");
        }
    }
    // ARM's second and third models: joint and lateral compliance.
    assert_eq!(inactive, [1, 2]);
}

/// On a branched tree (a torso with two arms), a step of one joint's geometry recomposes that
/// joint's subtree and copies the other branch: the same bits as the full rigid evaluation, for
/// a step of every chain parameter.
#[test]
fn restepped_rigid_kinematics_of_a_branched_tree_is_the_full_evaluation() {
    let r = robot(include_str!("../../../robots/agile-justin.toml"));
    let tree = r.tree();
    let q: Vec<f64> = (0..tree.nq()).map(|i| 0.3 * ((i as f64) * 1.7).sin()).collect();
    let mut base = TreeWorkspace::new(tree);
    tree.forward_into(&q, &mut base);
    let (mut full, mut restepped) = (TreeWorkspace::new(tree), TreeWorkspace::new(tree));
    let mut copied_a_branch = false;
    for k in 0..r.chain_values().len() {
        let mut values = r.chain_values().to_vec();
        values[k] += 1e-3;
        let stepped_tree = r.tree_for(&values).expect("stepped tree");
        let stepped: Vec<usize> = (0..tree.joints().len())
            .filter(|&j| stepped_tree.joints()[j].placement != tree.joints()[j].placement)
            .collect();
        stepped_tree.forward_into(&q, &mut full);
        stepped_tree.forward_into(&vec![0.1; tree.nq()], &mut restepped);
        stepped_tree.forward_restepped_into(&q, &base, &stepped, &mut restepped);
        assert_eq!(restepped.body, full.body, "parameter {k}");
        assert_eq!(restepped.joint_frame, full.joint_frame, "parameter {k}");
        assert_eq!(restepped.point, full.point, "parameter {k}");
        assert_eq!(restepped.joint_value, full.joint_value, "parameter {k}");
        // A later body the step left where it was: another branch, copied.
        copied_a_branch |= stepped
            .first()
            .is_some_and(|&s| (s + 1..tree.joints().len()).any(|j| full.body[j + 1] == base.body[j + 1]));
    }
    assert!(copied_a_branch);
}
