//! The same arm in MDH, classic DH and POE gives the same tool pose; a parameter of a URDF or
//! MDH chain moves its own joint's placement alone.

use armcomp_core::support::io::InputLimits;
use armcomp_urdf::robot_from_urdf;
use proptest::prelude::*;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use crate::common::{robot, root};

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn industrial_mdh_dh_poe_agree(q in prop::collection::vec(-3.2f64..3.2, 6)) {
        let mdh = robot("industrial-6dof.toml");
        let a = mdh.forward(&q).unwrap().point[mdh.tool()];
        for other in ["industrial-6dof-dh.toml", "industrial-6dof-poe.toml"] {
            let r = robot(other);
            let b = r.forward(&q).unwrap().point[r.tool()];
            let dp = (a.translation.vector - b.translation.vector).norm();
            let dr = (a.rotation.inverse() * b.rotation).angle();
            prop_assert!(dp < 1e-9, "{other}: position differs by {dp:e} m");
            prop_assert!(dr < 1e-9, "{other}: orientation differs by {dr:e} rad");
        }
    }
}

#[test]
fn parameter_counts_follow_the_conventions() {
    // MDH: 4 per joint + Hayati beta on joint 3; DH: 4 per joint; POE: 6 per joint.
    assert_eq!(robot("industrial-6dof.toml").chain_params().len(), 25);
    assert_eq!(robot("industrial-6dof-dh.toml").chain_params().len(), 24);
    assert_eq!(robot("industrial-6dof-poe.toml").chain_params().len(), 36);
    let names: Vec<_> = robot("industrial-6dof.toml")
        .chain_params()
        .iter()
        .map(|p| p.name.clone())
        .collect();
    assert!(names.contains(&"j3.beta".to_string()) && !names.contains(&"j2.beta".to_string()));
}

#[test]
fn hayati_beta_tilts_the_parallel_axis() {
    // A beta of 0.01 rad on joint 3 rotates the following link about y3: the tool moves by
    // about beta times its distance along z... compare with the MDH formula directly.
    let r = robot("industrial-6dof.toml");
    let mut values = r.chain_values().to_vec();
    let k = r.chain_params().iter().position(|p| p.name == "j3.beta").unwrap();
    values[k] = 0.01;
    let tree = r.tree_for(&values).unwrap();
    let q = [0.1, -0.3, 0.5, 0.2, -0.4, 0.6];
    let moved = tree.point_positions(&q)[r.tool()];
    let base = r.forward(&q).unwrap().point[r.tool()].translation.vector;
    // Independent composition: insert Ry(beta) between Tx(a2) and Rz(q3) by hand.
    use armcomp_core::model::geom::{rx, ry, rz, tx, tz};
    let d = std::f64::consts::PI / 180.0;
    let t = rz(q[0])
        * rx(-90.0 * d)
        * rz(q[1])
        * tx(0.4318)
        * ry(0.01)
        * rz(q[2])
        * tz(0.14909)
        * rx(-90.0 * d)
        * tx(0.02032)
        * rz(q[3])
        * tz(0.43307)
        * rx(90.0 * d)
        * rz(q[4])
        * rx(-90.0 * d)
        * rz(q[5])
        * tz(0.1);
    assert!((moved - t.translation.vector).norm() < 1e-12);
    assert!((moved - base).norm() > 1e-3, "beta must matter");
}

/// The shortcut a calibration's Jacobian takes for a URDF or MDH parameter (the one placement it
/// moves) against the whole tree built at the stepped values: that joint's placement, and
/// every other joint and body exactly as before.
#[test]
fn each_urdf_and_mdh_parameter_moves_the_one_placement_it_names() {
    let mut rng = StdRng::seed_from_u64(5);
    for robot in [
        robot_from_urdf(&root().join("robots/ur5.urdf"), InputLimits::default()).unwrap(),
        robot("talos-left-arm.toml"),
        robot("rock-drill.toml"),
        robot("industrial-6dof.toml"),
    ] {
        let chain = robot.chain();
        let values: Vec<f64> = robot
            .chain_values()
            .iter()
            .map(|v| v + rng.random_range(-0.01..0.01))
            .collect();
        let before = chain.tree(&values).unwrap();
        for k in 0..values.len() {
            let mut t = values.clone();
            t[k] += 1e-3;
            let after = chain.tree(&t).unwrap();
            let (j, placed) = chain
                .placement_moved_by(&t, k)
                .expect("every parameter belongs to a joint");
            let moved = after.joints()[j].placement;
            assert!(
                (moved.to_homogeneous() - placed.to_homogeneous()).abs().max() < 1e-14,
                "parameter {k}"
            );
            assert!(
                (moved.to_homogeneous() - before.joints()[j].placement.to_homogeneous())
                    .abs()
                    .max()
                    > 1e-5,
                "parameter {k} moves joint {j}"
            );
            for (i, (a, b)) in before.joints().iter().zip(after.joints()).enumerate() {
                if i != j {
                    assert_eq!(a.placement, b.placement, "parameter {k} moves joint {i} too");
                }
                assert_eq!(a.motion, b.motion, "parameter {k} changes joint {i}'s motion");
            }
            for (a, b) in before.bodies().iter().zip(after.bodies()) {
                assert_eq!(a.convention_frame, b.convention_frame, "parameter {k}");
            }
        }
    }
}
