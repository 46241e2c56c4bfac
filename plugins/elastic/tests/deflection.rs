//! Cantilever deflection against textbook values and a numerical integration of the beam
//! equation; joint compliance against a known torque; Eq. 5 against the composed chain.

use crate::common::{PENDULUM, perturbation_of, rel, robot, robot_issues};
use armcomp_core::model::geom::skew;
use armcomp_core::{Perturbation, TreeWorkspace};
use armcomp_elastic::tool_differential_world;
use nalgebra::{Matrix3, Vector3, Vector6};

const G: f64 = 9.81;

/// One link along x from a vertical joint, a beam with its cantilever model (error model 0),
/// tool at `l`; `link` adds to the link's table, `extra` appends TOML.
fn one_link(l: f64, link: &str, extra: &str, gravity: [f64; 3]) -> String {
    format!(
        r#"
name = "one-link"
gravity = [{}, {}, {}]
[kinematics]
type = "mdh"
[[kinematics.joints]]
name = "j1"
limits = [-3, 3]
[[links]]
name = "j1"
{link}
beam = {{ ei_y = 7.0e4, ei_z = 2.0e5, gj = 3.0e4 }}
[[points]]
name = "tool"
link = "j1"
xyz = [{l}, 0, 0]
[[error_models]]
type = "cantilever_deflection"
{extra}
"#,
        gravity[0], gravity[1], gravity[2]
    )
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * b.abs().max(1e-300)
}

fn assert_twist(got: &Vector6<f64>, want: [f64; 6]) {
    for k in 0..6 {
        if want[k] == 0.0 {
            assert!(got[k].abs() < 1e-15, "component {k}: got {got:?}, want {want:?}");
        } else {
            assert!(
                close(got[k], want[k], 1e-9),
                "component {k}: got {got:?}, want {want:?}"
            );
        }
    }
}

#[test]
fn uniform_load_matches_textbook() {
    let (l, m) = (2.0, 12.0);
    let r = robot(&one_link(l, "mass = 12.0\ncom = [1.0, 0, 0]", "", [0.0, 0.0, -G]));
    let (pert, _) = perturbation_of(&r, 0, &[1.0, 1.0], &[0.0], None);
    // Gravity along -z runs along the section width (link z): EI_z resists it.
    let w = m * G / l;
    let ei = 2.0e5;
    let tool = r.tree().point_index("tool").unwrap();
    assert_twist(
        &pert.point_twist[tool],
        [
            0.0,
            0.0,
            -w * l.powi(4) / (8.0 * ei),
            0.0,
            w * l.powi(3) / (6.0 * ei),
            0.0,
        ],
    );
}

#[test]
fn uniform_load_in_the_height_plane_uses_ei_y() {
    let (l, m) = (2.0, 12.0);
    // Gravity along -y lies in the plane the link swings in: the section height, EI_y.
    let r = robot(&one_link(l, "mass = 12.0", "", [0.0, -G, 0.0]));
    let (pert, _) = perturbation_of(&r, 0, &[1.0, 1.0], &[0.0], None);
    let w = m * G / l;
    let ei = 7.0e4;
    let tool = r.tree().point_index("tool").unwrap();
    assert_twist(
        &pert.point_twist[tool],
        [
            0.0,
            -w * l.powi(4) / (8.0 * ei),
            0.0,
            0.0,
            0.0,
            -w * l.powi(3) / (6.0 * ei),
        ],
    );
}

#[test]
fn tip_force_matches_textbook() {
    let (l, mp) = (1.5, 30.0);
    let r = robot(&one_link(l, "", &format!("[payload]\nmass = {mp}"), [0.0, 0.0, -G]));
    let (pert, _) = perturbation_of(&r, 0, &[1.0, 1.0], &[0.0], None);
    let p = mp * G;
    let ei = 2.0e5;
    let tool = r.tree().point_index("tool").unwrap();
    assert_twist(
        &pert.point_twist[tool],
        [
            0.0,
            0.0,
            -p * l.powi(3) / (3.0 * ei),
            0.0,
            p * l.powi(2) / (2.0 * ei),
            0.0,
        ],
    );
}

/// A beam link j1 of length `l` carrying a rigid link j2 whose mass sits at `com` (j2 frame).
fn beam_with_rigid_child(l: f64, m2: f64, com: [f64; 3]) -> String {
    format!(
        r#"
name = "two"
[kinematics]
type = "mdh"
[[kinematics.joints]]
name = "j1"
[[kinematics.joints]]
name = "j2"
kind = "fixed"
a = {l}
[[links]]
name = "j1"
beam = {{ ei_y = 7.0e4, ei_z = 2.0e5, gj = 3.0e4 }}
[[links]]
name = "j2"
mass = {m2}
com = [{}, {}, {}]
[[points]]
name = "tool"
link = "j2"
xyz = [0.5, 0, 0]
[[error_models]]
type = "cantilever_deflection"
"#,
        com[0], com[1], com[2]
    )
}

#[test]
fn tip_moment_adds_textbook_couple_terms() {
    let (l, m2, d) = (1.2, 20.0, 0.4);
    let r = robot(&beam_with_rigid_child(l, m2, [d, 0.0, 0.0]));
    let (pert, _) = perturbation_of(&r, 0, &[1.0, 1.0], &[0.0], None);
    let (p, mo, ei) = (m2 * G, m2 * G * d, 2.0e5);
    // Force P and couple M = P d about +y, both bending the tip down.
    let w = p * l.powi(3) / (3.0 * ei) + mo * l * l / (2.0 * ei);
    let slope = p * l * l / (2.0 * ei) + mo * l / ei;
    assert_twist(&pert.joint_twist[1], [0.0, 0.0, -w, 0.0, slope, 0.0]);
}

#[test]
fn torsion_matches_textbook() {
    let (l, m2, e) = (1.2, 20.0, 0.3);
    let r = robot(&beam_with_rigid_child(l, m2, [0.0, e, 0.0]));
    let (pert, _) = perturbation_of(&r, 0, &[1.0, 1.0], &[0.0], None);
    let (p, ei, gj) = (m2 * G, 2.0e5, 3.0e4);
    // The weight at lateral offset e twists the beam by T = -P e about x.
    assert_twist(
        &pert.joint_twist[1],
        [
            0.0,
            0.0,
            -p * l.powi(3) / (3.0 * ei),
            -p * e * l / gj,
            p * l * l / (2.0 * ei),
            0.0,
        ],
    );
}

#[test]
fn stiffness_scale_divides_the_deflection() {
    let r = robot(&one_link(2.0, "mass = 12.0", "", [0.0, 0.0, -G]));
    let (a, _) = perturbation_of(&r, 0, &[1.0, 1.0], &[0.3], None);
    let (b, _) = perturbation_of(&r, 0, &[2.5, 1.0], &[0.3], None);
    let tool = r.tree().point_index("tool").unwrap();
    assert!((a.point_twist[tool] / 2.5 - b.point_twist[tool]).norm() < 1e-15);
    assert!(a.point_twist[tool].norm() > 1e-5);
}

// ---------------------------------------------------------------------------------------------
// Two links against a numerical integration of the beam equation.

const TWO_LINK: &str = r#"
name = "two-link"
gravity = [0.8, -1.3, -9.7]
[kinematics]
type = "mdh"
[[kinematics.joints]]
name = "j1"
[[kinematics.joints]]
name = "j2"
a = 1.5
[[links]]
name = "j1"
mass = 20.0
com = [0.75, 0, 0]
beam = { ei_y = 2.0e5, ei_z = 3.0e5, gj = 1.0e5 }
[[links]]
name = "j2"
mass = 8.0
com = [0.6, 0.05, 0.0]
beam = { ei_y = 5.0e4, ei_z = 8.0e4, gj = 3.0e4 }
[[points]]
name = "tool"
link = "j2"
xyz = [1.2, 0.1, 0.0]
[[points]]
name = "marker"
link = "j2"
xyz = [0.6, 0.15, 0.04]
[payload]
mass = 3.0
[[error_models]]
type = "cantilever_deflection"
"#;

/// Displacement and rotation (world) along a cantilever from `start` along unit `x`, length `l`,
/// section axes `y`, `z`, rigidities `(ei_y, ei_z, gj)`, carrying a uniform load `w` (N/m) and
/// point masses `(position, force)`, by integrating dθ/ds = C·M(s), du/ds = θ × x with the
/// trapezoid rule. Returns the motion at every station `stations[i]`.
#[allow(clippy::too_many_arguments)]
fn integrate_beam(
    start: Vector3<f64>,
    x: Vector3<f64>,
    y: Vector3<f64>,
    z: Vector3<f64>,
    l: f64,
    rig: (f64, f64, f64),
    w: Vector3<f64>,
    masses: &[(Vector3<f64>, Vector3<f64>)],
    stations: &[f64],
) -> Vec<(Vector3<f64>, Vector3<f64>)> {
    let c: Matrix3<f64> = y * y.transpose() / rig.0 + z * z.transpose() / rig.1 + x * x.transpose() / rig.2;
    // Internal moment at station s: everything beyond s acting about the axis point there.
    let moment = |s: f64| -> Vector3<f64> {
        let r = start + x * s;
        let mut m = x.cross(&w) * ((l - s) * (l - s) / 2.0);
        for (p, f) in masses {
            m += (p - r).cross(f);
        }
        m
    };
    let n = 200_000;
    let h = l / n as f64;
    let mut out = vec![(Vector3::zeros(), Vector3::zeros()); stations.len()];
    let (mut th, mut u) = (Vector3::zeros(), Vector3::zeros());
    let mut k_prev = c * moment(0.0);
    let mut du_prev = th.cross(&x);
    for i in 1..=n {
        let (s0, s1) = ((i - 1) as f64 * h, i as f64 * h);
        let k = c * moment(s1);
        let th_new = th + (k_prev + k) * (h / 2.0);
        let du = th_new.cross(&x);
        let u_new = u + (du_prev + du) * (h / 2.0);
        for (st, o) in stations.iter().zip(out.iter_mut()) {
            if *st > s0 && *st <= s1 {
                let t = (st - s0) / h;
                *o = (u + (u_new - u) * t, th + (th_new - th) * t);
            }
        }
        th = th_new;
        u = u_new;
        k_prev = k;
        du_prev = du;
    }
    out
}

fn world_motion(frame: &nalgebra::Isometry3<f64>, t: &Vector6<f64>) -> (Vector3<f64>, Vector3<f64>) {
    (
        frame.rotation * Vector3::new(t[0], t[1], t[2]),
        frame.rotation * Vector3::new(t[3], t[4], t[5]),
    )
}

#[test]
fn two_link_arm_matches_numerical_beam_integration() {
    let r = robot(TWO_LINK);
    let q = [0.3, 0.7];
    let (pert, f) = perturbation_of(&r, 0, &[1.0; 4], &q, None);
    let g = r.gravity();
    let tool = r.tree().point_index("tool").unwrap();
    let marker = r.tree().point_index("marker").unwrap();
    let p_tool = f.point[tool].translation.vector;
    let p_marker = f.point[marker].translation.vector;
    let vertical = Vector3::z(); // both joint axes (link z) are vertical

    // Link 1: from the origin to the seat of j2.
    let s1 = f.joint_frame[0].translation.vector;
    let e1 = f.joint_frame[1].translation.vector;
    let l1 = (e1 - s1).norm();
    let x1 = (e1 - s1) / l1;
    let y1 = vertical;
    let z1 = x1.cross(&y1);
    let com2 = f.body[2].transform_point(&Vector3::new(0.6, 0.05, 0.0).into()).coords;
    let masses1 = [(com2, g * 8.0), (p_tool, g * 3.0)];
    let ref1 = integrate_beam(
        s1,
        x1,
        y1,
        z1,
        l1,
        (2.0e5, 3.0e5, 1.0e5),
        g * (20.0 / l1),
        &masses1,
        &[l1],
    );
    let (u, th) = world_motion(&f.joint_frame[1], &pert.joint_twist[1]);
    assert!(rel(&u, &ref1[0].0) < 1e-6, "{u} vs {}", ref1[0].0);
    assert!(rel(&th, &ref1[0].1) < 1e-6, "{th} vs {}", ref1[0].1);

    // Link 2: from the seat of j2 to the tool, own weight uniform, payload at the tip.
    let s2 = e1;
    let l2 = (p_tool - s2).norm();
    let x2 = (p_tool - s2) / l2;
    let y2 = (vertical - x2 * x2.dot(&vertical)).normalize();
    let z2 = x2.cross(&y2);
    let sm = (p_marker - s2).dot(&x2);
    let ref2 = integrate_beam(
        s2,
        x2,
        y2,
        z2,
        l2,
        (5.0e4, 8.0e4, 3.0e4),
        g * (8.0 / l2),
        &[(p_tool, g * 3.0)],
        &[l2, sm],
    );
    let (u, th) = world_motion(&f.point[tool], &pert.point_twist[tool]);
    assert!(rel(&u, &ref2[0].0) < 1e-6, "{u} vs {}", ref2[0].0);
    assert!(rel(&th, &ref2[0].1) < 1e-6, "{th} vs {}", ref2[0].1);
    // The marker sits off the axis at an intermediate station: carried rigidly by the section.
    let (um, thm) = world_motion(&f.point[marker], &pert.point_twist[marker]);
    let off = p_marker - (s2 + x2 * sm);
    let want = ref2[1].0 + ref2[1].1.cross(&off);
    assert!(rel(&um, &want) < 1e-6, "{um} vs {want}");
    assert!(rel(&thm, &ref2[1].1) < 1e-6);
}

// ---------------------------------------------------------------------------------------------
// Joint compliance.

/// The pendulum (a joint about z, gravity along −y, 10 kg at 0.8 m, the tool at 1 m) with
/// joint compliance `c` in rad/(N m).
fn pendulum(c: f64) -> String {
    format!("{PENDULUM}[[error_models]]\ntype = \"joint_compliance\"\ncompliance = {{ j1 = {c:e} }}\n")
}

#[test]
fn compliance_under_known_torque_gives_expected_angle() {
    let r = robot(&pendulum(2.0e-4));
    let c = 2.0e-4;
    for q in [0.0, 0.4, 2.0] {
        let (pert, _) = perturbation_of(&r, 0, &[c], &[q], None);
        // Torque about the axis z of the weight at 0.8 m: τ = -m g r cos q.
        let tau = -10.0 * G * 0.8 * f64::cos(q);
        assert!(
            close(pert.joint_offset[0], c * tau, 1e-12),
            "q={q}: {}",
            pert.joint_offset[0]
        );
    }
    // Through the whole model: the tool drops by the rotation of the link.
    let f = r.forward(&[0.0]).unwrap();
    let angle = c * 10.0 * G * 0.8;
    let p = f.point[0].translation.vector;
    assert!((p - Vector3::new(angle.cos(), -angle.sin(), 0.0)).norm() < 1e-12, "{p}");
}

/// Two parallel horizontal joints, the second coupled to the first as `b = -a` (a parallelogram
/// that keeps link `b` level): 8 kg at 0.5 m on link `a` (1 m long), 5 kg at 0.5 m on link `b`.
#[test]
fn coupled_joint_compliance_carries_the_generalised_load() {
    let (ca, cb) = (3.0e-4, 1.0e-4);
    let r = robot(&format!(
        r#"
name = "parallelogram"
[kinematics]
type = "mdh"
[[kinematics.joints]]
name = "a"
alpha = 1.5707963267948966
[[kinematics.joints]]
name = "b"
a = 1.0
mimic = {{ joints = ["a"], multipliers = [-1.0] }}
[[links]]
name = "a"
mass = 8.0
com = [0.5, 0, 0]
[[links]]
name = "b"
mass = 5.0
com = [0.5, 0, 0]
[[points]]
name = "tool"
link = "b"
xyz = [0.7, 0, 0]
[[error_models]]
type = "joint_compliance"
compliance = {{ a = {ca:e}, b = {cb:e} }}
"#
    ));
    for q in [0.0, 0.6, -1.2] {
        let (pert, _) = perturbation_of(&r, 0, &[ca, cb], &[q], None);
        // Gravity torque about the axes (0, -1, 0): minus weight times horizontal lever.
        let tau_a = -G * (8.0 * 0.5 * q.cos() + 5.0 * (q.cos() + 0.5));
        let tau_b = -G * 5.0 * 0.5;
        // The drive of `a` holds τ_a + (-1)·τ_b: the linkage carries link b's own moment.
        let dq_a = ca * (tau_a - tau_b);
        assert!(
            close(pert.joint_offset[0], dq_a, 1e-12),
            "q={q}: {}",
            pert.joint_offset[0]
        );
        // `b` follows the deflected `a` (stays level) and gives way by the coupling's own
        // compliance.
        let want_b = -dq_a + cb * tau_b;
        assert!(
            close(pert.joint_offset[1], want_b, 1e-12),
            "q={q}: {}",
            pert.joint_offset[1]
        );
    }
}

#[test]
fn lateral_compliance_tilts_with_the_bending_moment() {
    // The one-link arm (its cantilever model first), 10 kg at 0.5 m, a lateral compliance.
    let lateral = "[[error_models]]\ntype = \"lateral_compliance\"\ncompliance = { j1 = [1.0e-5, 3.0e-5] }";
    let r = robot(&one_link(
        1.0,
        "mass = 10.0\ncom = [0.5, 0, 0]",
        lateral,
        [0.0, 0.0, -G],
    ));
    for q in [0.0, 0.9] {
        let (pert, _) = perturbation_of(&r, 1, &[1.0e-5, 3.0e-5], &[q], None);
        // Moment of 10 kg at 0.5 m along (cos q, sin q, 0) under -z gravity: r × F.
        let m = Vector3::new(0.5 * q.cos(), 0.5 * q.sin(), 0.0).cross(&Vector3::new(0.0, 0.0, -10.0 * G));
        let want = Vector6::new(0.0, 0.0, 0.0, 1.0e-5 * m.x, 3.0e-5 * m.y, 0.0);
        assert!(
            (pert.joint_twist[0] - want).norm() < 1e-15 * 1e6,
            "{} vs {want}",
            pert.joint_twist[0]
        );
        assert!(close(pert.joint_twist[0][3], want[3], 1e-12) || want[3] == 0.0);
    }
}

// ---------------------------------------------------------------------------------------------
// Eq. 5 against the composed chain.

fn scaled(p: &Perturbation, s: f64) -> Perturbation {
    let mut o = p.clone();
    o.joint_twist.iter_mut().for_each(|t| *t *= s);
    o.point_twist.iter_mut().for_each(|t| *t *= s);
    o.joint_offset.iter_mut().for_each(|v| *v *= s);
    o
}

#[test]
fn eq5_agrees_with_the_composed_chain_to_first_order() {
    let r = robot(TWO_LINK);
    let q = [0.3, 0.7];
    let (mut pert, rigid) = perturbation_of(&r, 0, &[1.0; 4], &q, None);
    // Add joint offsets and a base-seat twist so every kind of entry is exercised.
    pert.joint_offset[0] = 2e-3;
    pert.joint_offset[1] = -1e-3;
    pert.joint_twist[0] = Vector6::new(1e-3, -2e-3, 5e-4, 1e-3, 2e-3, -1e-3);
    let tool = r.tree().point_index("tool").unwrap();
    let mut ws = TreeWorkspace::new(r.tree());
    let mut last = f64::INFINITY;
    for s in [1e-1, 1e-2, 1e-3] {
        let p = scaled(&pert, s);
        let (d, dth) = tool_differential_world(r.tree(), &rigid, &p, tool);
        r.tree().forward_perturbed_into(&q, &p, &mut ws);
        let composed = ws.point[tool].translation.vector - rigid.point[tool].translation.vector;
        let drot = (ws.point[tool].rotation * rigid.point[tool].rotation.inverse()).scaled_axis();
        let err = rel(&d, &composed).max(rel(&dth, &drot));
        // First order: the discrepancy shrinks with the perturbation.
        assert!(err < 0.05 * s / 1e-1, "s={s}: relative discrepancy {err}");
        assert!(err < last / 5.0, "s={s}: {err} did not shrink from {last}");
        last = err;
    }
    // The mapping matrix of Eq. 5 for one frame is the adjoint: check one term by hand.
    let t = rigid.joint_frame[1].inverse() * rigid.point[tool];
    let (n, p) = (t.rotation.to_rotation_matrix().into_inner(), t.translation.vector);
    let mut m6 = nalgebra::Matrix6::zeros();
    m6.fixed_view_mut::<3, 3>(0, 0).copy_from(&n.transpose());
    m6.fixed_view_mut::<3, 3>(0, 3).copy_from(&(skew(&p) * n).transpose());
    m6.fixed_view_mut::<3, 3>(3, 3).copy_from(&n.transpose());
    let delta = Vector6::new(1e-4, 2e-4, -3e-4, 1e-5, -2e-5, 3e-5);
    let mut only = Perturbation::zeros(r.tree());
    only.joint_twist[1] = delta;
    let d = armcomp_elastic::tool_differential(r.tree(), &rigid, &only, tool);
    assert!((d - m6 * delta).norm() < 1e-16, "{d} vs {}", m6 * delta);
}

// ---------------------------------------------------------------------------------------------
// Validation.

#[test]
fn bad_specs_are_reported_with_field_paths() {
    let base = one_link(1.0, "mass = 1.0", "", [0.0, 0.0, -G]);
    let src = format!(
        "{base}\n[[error_models]]\ntype = \"joint_compliance\"\ncompliance = {{ j9 = 1e-6 }}\n\n[[error_models]]\ntype = \"joint_compliance\"\ncompliance = {{ j1 = -1e-6 }}\n\n[[error_models]]\ntype = \"cantilever_deflection\"\nlinks = [\"nope\"]\nei_scale = {{ j1 = 0.0 }}\n"
    );
    let issues = robot_issues(&src);
    let has = |p: &str| issues.iter().any(|i| i.starts_with(p));
    assert!(
        has("error_models[1].compliance.j9: joint `j9` does not exist"),
        "{issues:?}"
    );
    assert!(
        has("error_models[2].compliance.j1: expected a compliance"),
        "{issues:?}"
    );
    assert!(
        has("error_models[3].links[0]: link `nope` does not exist"),
        "{issues:?}"
    );
    assert!(has("error_models[3].ei_scale.j1"), "{issues:?}");
}

// ---------------------------------------------------------------------------------------------
// Static equilibrium of a very elastic joint.

#[test]
fn equilibrium_solves_the_fixed_point_and_reports_failure() {
    use armcomp_elastic::{ElasticError, EquilibriumParams, EquilibriumWorkspace, solve_equilibrium};
    let r = robot(&pendulum(3.0e-3));
    let (c, k) = (3.0e-3, 10.0 * G * 0.8);
    let q = 0.3;
    // Equilibrium: dq = -c k cos(q + dq); solved here by bisection on [-1, 0].
    let f = |d: f64| d + c * k * (q + d).cos();
    let (mut lo, mut hi) = (-1.0, 0.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if f(mid) > 0.0 { hi = mid } else { lo = mid }
    }
    let want = 0.5 * (lo + hi);
    let mut ws = r.workspace();
    let mut eq = EquilibriumWorkspace::new(&r);
    let rep = solve_equilibrium(&r, &[q], None, &EquilibriumParams::default(), &mut ws, &mut eq).unwrap();
    assert!(
        (ws.perturbation.joint_offset[0] - want).abs() < 1e-11,
        "{} vs {want}",
        ws.perturbation.joint_offset[0]
    );
    assert!(rep.iterations > 2);
    // The one-shot model differs from equilibrium by more than the tolerance: the iteration matters.
    assert!((c * -k * q.cos() - want).abs() > 1e-3);
    // Too few iterations: reported, with the best iterate in the workspace.
    let opts = EquilibriumParams {
        max_iterations: 3,
        tolerance: 1e-14,
    };
    match solve_equilibrium(&r, &[q], None, &opts, &mut ws, &mut eq) {
        Err(ElasticError::NotConverged { iterations: 3, change }) => assert!(change > 1e-14),
        other => panic!("expected NotConverged, got {other:?}"),
    }
    assert!((ws.perturbation.joint_offset[0] - want).abs() < 0.05);
}

/// A horizontal telescopic section (prismatic joint, axis horizontal) of mass `m`, the tool
/// at its tip; `extra` goes into the cantilever model.
fn telescope(extra: &str) -> String {
    format!(
        r#"
name = "telescope"
gravity = [0, 0, -9.81]
[kinematics]
type = "mdh"
[[kinematics.joints]]
name = "j1"
kind = "prismatic"
alpha = 1.5707963267948966
limits = [0, 2]
[[links]]
name = "j1"
mass = 6.0
beam = {{ ei_y = 5.0e4, ei_z = 5.0e4, gj = 3.0e4 }}
[[points]]
name = "tool"
link = "j1"
xyz = [0, 0, 0]
[[error_models]]
type = "cantilever_deflection"
{extra}
"#
    )
}

#[test]
fn a_telescopic_section_loads_the_cantilever_with_the_part_that_is_out() {
    let (m, ei, section) = (6.0, 5.0e4, 0.5);
    let with_section = robot(&telescope("section_length = { j1 = 0.5 }"));
    let without = robot(&telescope(""));
    let tool = with_section.tree().point_index("tool").unwrap();
    // Tip deflection of a cantilever of free length d under q per length: q d⁴ / (8 EI).
    let tip = |q: f64, d: f64| q * d.powi(4) / (8.0 * ei);
    for (d, q_section) in [
        // Partly out: the section's weight per length over the free part.
        (0.2, m * G / section),
        (0.4, m * G / section),
        // Pulled past its length: the whole weight over the free length.
        (0.6, m * G / 0.6),
    ] {
        for (r, q) in [(&with_section, q_section), (&without, m * G / d)] {
            let (pert, _) = perturbation_of(r, 0, &[1.0, 1.0], &[d], None);
            let got = pert.point_twist[tool].fixed_rows::<3>(0).norm();
            assert!(
                close(got, tip(q, d), 1e-9),
                "extension {d} m: tip deflection {got} m, textbook {} m",
                tip(q, d)
            );
        }
    }
    // The load grows with the extension: twice as far out, sixteen times the deflection
    // (d⁴ at a fixed weight per length), against eight (d³) when the weight spreads.
    let deflection = |r: &armcomp_core::Robot, d: f64| {
        perturbation_of(r, 0, &[1.0, 1.0], &[d], None).0.point_twist[tool]
            .fixed_rows::<3>(0)
            .norm()
    };
    assert!(close(
        deflection(&with_section, 0.4) / deflection(&with_section, 0.2),
        16.0,
        1e-9
    ));
    assert!(close(deflection(&without, 0.4) / deflection(&without, 0.2), 8.0, 1e-9));
}

#[test]
fn a_section_length_needs_a_sliding_link_and_a_positive_length() {
    let revolute = one_link(1.0, "mass = 1.0", "section_length = { j1 = 0.5 }", [0.0, 0.0, -G]);
    let issues = robot_issues(&revolute);
    assert!(
        issues
            .iter()
            .any(|i| i.contains("section_length.j1") && i.contains("not prismatic")),
        "{issues:?}"
    );
    let issues = robot_issues(&telescope("section_length = { j1 = -0.5 }"));
    assert!(
        issues
            .iter()
            .any(|i| i.contains("section_length.j1") && i.contains("positive length")),
        "{issues:?}"
    );
    let issues = robot_issues(&telescope("section_length = { boom = 0.5 }"));
    assert!(
        issues
            .iter()
            .any(|i| i.contains("section_length.boom") && i.contains("not modelled")),
        "{issues:?}"
    );
}
