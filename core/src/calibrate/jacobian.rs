//! Evaluating the model on the samples and its Jacobian: twists for geometry, exact columns
//! for markers, the first-order effect of the change of deformation for error models (and,
//! in the exact form, for geometry, whose moment arms the deformation depends on).

use nalgebra::{DMatrix, DVector, Isometry3, Vector3, Vector6};

use crate::error::Result;
use crate::geom::exp_twist;
use crate::measurement::Sample;
use crate::param::{ParamInfo, Quantity};
use crate::perturbation::Perturbation;
use crate::robot::{Conditions, Robot};
use crate::tree::KinematicTree;
use crate::workspace::PointSensitivity;

use super::*;

/// The model's point and marker rotation at every sample, evaluated in parallel (each sample
/// on its own, so the result does not depend on the thread count).
pub(super) fn evaluate(robot: &Robot, d: &Decoded, samples: &[Sample]) -> Evaluation {
    let (world, marker_rot) = samples
        .par_iter()
        .map_init(
            || robot.workspace(),
            |ws, s| {
                robot.forward_with_into(&d.tree, &d.errors, &s.q, Conditions::of(s), ws);
                let point = &d.tree.points()[s.point];
                let rot = ws.frames.body[point.body].rotation.to_rotation_matrix().into_inner()
                    * d.tree.bodies()[point.body]
                        .convention_frame
                        .rotation
                        .to_rotation_matrix()
                        .into_inner();
                (ws.frames.point[s.point].translation.vector, rot)
            },
        )
        .unzip();
    Evaluation { world, marker_rot }
}

pub(super) fn to_meas(t: &Isometry3<f64>, world: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
    world.iter().map(|p| t.transform_point(&(*p).into()).coords).collect()
}

impl Problem<'_> {
    pub(super) fn predict(&self, theta: &[f64]) -> Result<(Decoded, Evaluation, Vec<Vector3<f64>>)> {
        let d = self.space.decode(self.robot, theta)?;
        let e = evaluate(self.robot, &d, self.samples);
        let meas = to_meas(&d.t_meas_base, &e.world);
        Ok((d, e, meas))
    }

    /// ½χ² of `stage` with the priors of `free` centred at `theta0`: what Levenberg–Marquardt
    /// minimises.
    pub(super) fn cost(&self, stage: &Stage, theta0: &[f64], free: &[usize]) -> f64 {
        let r = self.residuals(&to_meas(&stage.d.t_meas_base, &stage.e.world));
        self.cost_of(&stage.theta, theta0, free, &r)
    }

    pub(super) fn cost_of(&self, theta: &[f64], theta0: &[f64], free: &[usize], r: &DVector<f64>) -> f64 {
        let prior: f64 = free
            .iter()
            .map(|&k| ((theta[k] - theta0[k]) / self.space.params[k].info.sigma).powi(2))
            .sum();
        0.5 * (r.norm_squared() + prior)
    }

    /// The RMS of `stage`'s 3-D residuals over what the noise alone gives (√3 σ).
    pub(super) fn rms_over_noise(&self, stage: &Stage) -> f64 {
        let r = self.residuals(&to_meas(&stage.d.t_meas_base, &stage.e.world));
        (r.norm_squared() / (3.0 * self.samples.len() as f64)).sqrt()
    }

    /// Measurement residuals `(p̂ − p) / σ`, three per sample.
    pub(super) fn residuals(&self, predicted: &[Vector3<f64>]) -> DVector<f64> {
        DVector::from_iterator(
            3 * self.samples.len(),
            predicted.iter().zip(self.samples).flat_map(|(p, s)| {
                let r = (p - s.position) / self.sigma;
                [r.x, r.y, r.z]
            }),
        )
    }

    /// How each Jacobian column of `free` is computed at `theta`.
    pub(super) fn column_plans(
        &self,
        theta: &[f64],
        d: &Decoded,
        free: &[usize],
        form: JacobianForm,
    ) -> Result<Vec<ColumnPlan>> {
        let space = self.space;
        free.iter()
            .map(|&k| {
                let p = &space.params[k];
                Ok(match p.group {
                    ParamGroup::Marker(i) => ColumnPlan::Marker {
                        point: self.robot.markers()[i],
                        axis: (k - space.marker_offset) % 3,
                    },
                    ParamGroup::Base => {
                        let (mut t, h) = step(theta, k, p);
                        t[k] += h;
                        ColumnPlan::Base {
                            from: space.base_pose(theta),
                            to: space.base_pose(&t),
                            h,
                        }
                    }
                    ParamGroup::ErrorModel(i) => {
                        let (_, h) = step(theta, k, p);
                        let mut values = d.errors[i].clone();
                        values[k - space.error_offsets[i]] += h;
                        if self.robot.error_models()[i].adjusts_loads() {
                            let mut errors = d.errors.clone();
                            errors[i] = values;
                            ColumnPlan::Loads { errors, h }
                        } else {
                            ColumnPlan::Model { model: i, values, h }
                        }
                    }
                    ParamGroup::Geometry => {
                        let (mut t, h) = step(theta, k, p);
                        t[k] += h;
                        let tree = space.tree(self.robot, &t)?;
                        let deformed = form == JacobianForm::Exact && self.robot.deforms_at(&d.errors);
                        geometry_plan(&d.tree, tree, h, deformed)
                    }
                })
            })
            .collect()
    }

    /// Jacobian of the measurement residuals with respect to the parameters `free`.
    ///
    /// Geometry that moves joint placements and point frames is differentiated through
    /// first-order twists at the placed frames: a few vector operations per sample instead of a
    /// forward kinematics run. On deformed robots the held `form` keeps the deformation as it
    /// is; the exact form adds the deformation's change (the models re-evaluated on the
    /// stepped rigid kinematics, no deformed forward pass), mapped to the point at the deformed
    /// frames ([`PointSensitivity`], one per sample). Error-model parameters are
    /// mapped the same way from the change of that model's deformation alone. Geometry that
    /// changes a joint's motion and load-adjusting models difference the full model.
    pub(super) fn jacobian(
        &self,
        theta: &[f64],
        d: &Decoded,
        e: &Evaluation,
        free: &[usize],
        form: JacobianForm,
    ) -> Result<DMatrix<f64>> {
        let plans = self.column_plans(theta, d, free, form)?;
        let ncols = plans.len();
        let r_meas = d.t_meas_base.rotation.to_rotation_matrix().into_inner();
        let n_models = self.robot.error_models().len();
        let rows: Vec<Vec<f64>> = self
            .samples
            .par_iter()
            .enumerate()
            .map_init(
                || {
                    let pert = Perturbation::zeros(&d.tree);
                    (
                        self.robot.workspace(),
                        self.robot.workspace(),
                        vec![pert.clone(); n_models],
                        pert.clone(),
                        pert,
                        vec![Isometry3::identity(); d.tree.joints().len()],
                        PointSensitivity::default(),
                    )
                },
                |(ws, ws_fd, base_perts, scratch, stepped, placed, sensitivity), (s_idx, s)| {
                    let cond = Conditions::of(s);
                    self.robot.forward_with_into(&d.tree, &d.errors, &s.q, cond, ws);
                    for (i, bp) in base_perts.iter_mut().enumerate() {
                        bp.clear();
                        self.robot.model_perturbation_into(i, &d.tree, &d.errors[i], s, ws, bp);
                    }
                    if n_models > 0 {
                        sensitivity.update(&d.tree, &ws.frames, &ws.perturbation, s.point);
                    }
                    let body = d.tree.points()[s.point].body;
                    let support = d.tree.support(body);
                    let p = e.world[s_idx];
                    // Geometry moves a joint's placement, which the deformation's twist
                    // follows: its twist acts at the placed frame before that twist (and a
                    // point's before its own), not at the deformed one.
                    let frames = &ws.frames;
                    let deformation = &ws.perturbation;
                    for &j in support {
                        placed[j] = frames.joint_frame[j];
                        if n_models > 0 {
                            placed[j] *= exp_twist(&deformation.joint_twist[j]).inverse();
                        }
                    }
                    let point_frame = if n_models > 0 {
                        frames.point[s.point] * exp_twist(&deformation.point_twist[s.point]).inverse()
                    } else {
                        frames.point[s.point]
                    };
                    let effect_at = |f: &Isometry3<f64>, xi: &Vector6<f64>| -> Vector3<f64> {
                        let v = f.rotation * xi.fixed_rows::<3>(0);
                        let w = f.rotation * xi.fixed_rows::<3>(3);
                        v + w.cross(&(p - f.translation.vector))
                    };
                    let mut row = vec![0.0; 3 * ncols];
                    for (c, plan) in plans.iter().enumerate() {
                        let dp_meas = match plan {
                            ColumnPlan::Marker { point, axis } => {
                                if *point != s.point {
                                    continue;
                                }
                                r_meas * e.marker_rot[s_idx].column(*axis)
                            }
                            ColumnPlan::Base { from, to, h } => {
                                (to.transform_point(&p.into()) - from.transform_point(&p.into())) / *h
                            }
                            ColumnPlan::Twists {
                                joints,
                                points,
                                deformation,
                            } => {
                                let mut dp = Vector3::zeros();
                                if let Some((tree, stepped, h)) = deformation {
                                    self.robot.deformation_restepped_into(
                                        tree, &d.errors, &s.q, cond, &ws.rigid, stepped, ws_fd,
                                    );
                                    scratch.set_difference(&ws_fd.perturbation, &ws.perturbation, 1.0 / *h);
                                    dp += sensitivity.effect(scratch);
                                }
                                for (j, xi) in joints {
                                    if support.contains(j) {
                                        dp += effect_at(&placed[*j], xi);
                                    }
                                }
                                for (i, xi) in points {
                                    if *i == s.point {
                                        dp += effect_at(&point_frame, xi);
                                    }
                                }
                                r_meas * dp
                            }
                            ColumnPlan::Loads { errors, h } => {
                                // A changed load changes what every elastic model does.
                                self.robot.forward_with_into(&d.tree, errors, &s.q, cond, ws_fd);
                                let dp = (ws_fd.frames.point[s.point].translation.vector
                                    - ws.frames.point[s.point].translation.vector)
                                    / *h;
                                r_meas * dp
                            }
                            ColumnPlan::Finite { tree, h } => {
                                self.robot.forward_with_into(tree, &d.errors, &s.q, cond, ws_fd);
                                let dp = (ws_fd.frames.point[s.point].translation.vector
                                    - ws.frames.point[s.point].translation.vector)
                                    / *h;
                                r_meas * dp
                            }
                            ColumnPlan::Model { model, values, h } => {
                                stepped.clear();
                                self.robot
                                    .model_perturbation_into(*model, &d.tree, values, s, ws, stepped);
                                scratch.set_difference(stepped, &base_perts[*model], 1.0 / *h);
                                r_meas * sensitivity.effect(scratch)
                            }
                        };
                        for a in 0..3 {
                            row[3 * c + a] = dp_meas[a] / self.sigma;
                        }
                    }
                    row
                },
            )
            .collect();
        let mut jac = DMatrix::zeros(3 * self.samples.len(), ncols);
        for (s_idx, row) in rows.iter().enumerate() {
            for c in 0..ncols {
                for a in 0..3 {
                    jac[(3 * s_idx + a, c)] = row[3 * c + a];
                }
            }
        }
        Ok(jac)
    }
}

/// The column plan of a geometry parameter whose step `h` turns `tree` into `stepped`; with
/// `deformed`, the exact form that adds the deformation's change.
pub(super) fn geometry_plan(tree: &KinematicTree, stepped: KinematicTree, h: f64, deformed: bool) -> ColumnPlan {
    let same_motion = tree
        .joints()
        .iter()
        .zip(stepped.joints())
        .all(|(a, b)| a.motion == b.motion && a.coordinate == b.coordinate);
    if !same_motion {
        return ColumnPlan::Finite { tree: stepped, h };
    }
    let twist = |a: &Isometry3<f64>, b: &Isometry3<f64>| -> Option<Vector6<f64>> {
        let rel = a.inverse() * b;
        let v = rel.translation.vector / h;
        let w = rel.rotation.scaled_axis() / h;
        let xi = Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z);
        (xi != Vector6::zeros()).then_some(xi)
    };
    let joints: Vec<(usize, Vector6<f64>)> = tree
        .joints()
        .iter()
        .zip(stepped.joints())
        .enumerate()
        .filter_map(|(j, (a, b))| twist(&a.placement, &b.placement).map(|xi| (j, xi)))
        .collect();
    let points = tree
        .points()
        .iter()
        .zip(stepped.points())
        .enumerate()
        .filter_map(|(i, (a, b))| twist(&a.local, &b.local).map(|xi| (i, xi)))
        .collect();
    let deformation = deformed.then(|| {
        let moved = joints.iter().map(|&(j, _)| j).collect();
        (stepped, moved, h)
    });
    ColumnPlan::Twists {
        joints,
        points,
        deformation,
    }
}

/// The size a parameter of this kind typically has when it matters (SI): 10 mm, 0.6°, 1 %,
/// 1e-4 rad/(N m), 0.1 kg, ...
pub(super) fn typical_size(info: &ParamInfo) -> f64 {
    match info.quantity {
        Quantity::Length | Quantity::Angle | Quantity::Dimensionless => 1e-2,
        Quantity::Compliance => 1e-4,
        Quantity::Mass => 0.1,
        Quantity::Rigidity => 1e3,
        Quantity::PerKelvin => 1e-6,
        Quantity::Other(_) => 1e-3,
    }
}

/// The scale a parameter's changes are judged at: its prior's standard deviation, or its
/// kind's [`typical_size`] when it has none.
pub(super) fn typical_scale(info: &ParamInfo) -> f64 {
    if info.sigma.is_finite() {
        info.sigma
    } else {
        typical_size(info)
    }
}

/// A copy of `theta` and a forward-difference step for parameter `k`, signed to stay within
/// the upper bound. Steps are 1e-6 of the value or of a typical scale, whichever is larger.
///
/// The typical scales are generous: a parameter that starts at zero (every candidate effect of
/// the diagnosis does) is stepped by the typical scale alone, and the step must move the tool
/// well above the round-off of metre-sized positions (1e-16 m) even under small loads. A
/// compliance stepped by 1e-13 rad/(N m) under the 0.1 N m of a lateral moment moves it by
/// 1e-14 m, which the identifiability analysis cannot tell from zero.
pub(super) fn step(theta: &[f64], k: usize, p: &SpaceParam) -> (Vec<f64>, f64) {
    let mut h = 1e-6 * theta[k].abs().max(typical_scale(&p.info));
    if theta[k] + h > p.info.upper {
        h = -h;
    }
    (theta.to_vec(), h)
}

/// Sensitivity of every marker's measured position at each pose to the parameters `identify`
/// selects (as for [`calibrate`]): `3 × markers` rows per pose in pose order, one column per
/// parameter (m per SI unit). Returns the matrix and the parameter names.
pub fn identification_jacobian(
    robot: &Robot,
    poses: &[Vec<f64>],
    identify: &[String],
) -> Result<(DMatrix<f64>, Vec<String>)> {
    let samples: Vec<Sample> = poses.iter().flat_map(|q| marker_samples(robot, q)).collect();
    samples_jacobian(robot, &samples, identify)
}

/// One sample per marker of `robot` at configuration `q` (measured positions zero): what
/// measuring every marker there would give, for planning.
pub fn marker_samples(robot: &Robot, q: &[f64]) -> Vec<Sample> {
    robot
        .markers()
        .iter()
        .map(|&m| Sample {
            q: q.to_vec(),
            point: m,
            position: Vector3::zeros(),
            orientation: None,
            payload: None,
            temperature: None,
            torque: None,
        })
        .collect()
}

/// [`identification_jacobian`] at the configurations, points and conditions (payload,
/// temperature) of `samples`: three rows per sample, in sample order; their measured
/// positions are not used.
pub fn samples_jacobian(robot: &Robot, samples: &[Sample], identify: &[String]) -> Result<(DMatrix<f64>, Vec<String>)> {
    for s in samples {
        robot.tree().check_q(&s.q)?;
    }
    let space = ParameterSpace::new(robot);
    let selected = space.select(robot, identify)?;
    let problem = Problem {
        robot,
        space: &space,
        samples,
        sigma: 1.0,
    };
    let theta = space.initial();
    let (d, e, _) = problem.predict(&theta)?;
    let jac = problem.jacobian(&theta, &d, &e, &selected, JacobianForm::Exact)?;
    Ok((
        jac,
        selected.iter().map(|&k| space.params[k].info.name.clone()).collect(),
    ))
}
