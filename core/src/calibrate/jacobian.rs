//! Evaluating the model on the samples and its Jacobian: twists for geometry, exact columns
//! for markers, the first-order effect of the change of deformation for error models (and,
//! in the exact form, for geometry, whose moment arms the deformation depends on).

use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Vector3, Vector6};

use super::{
    ColumnPlan, Decoded, Evaluation, JacobianForm, Noise, ParamGroup, ParameterSpace, PlaneGap, Problem, SpaceParam,
    Stage,
};
use crate::algorithms::evaluate::AngleStats;
use crate::data::measurement::Sample;
use crate::error::Result;
use crate::kinematics::workspace::PointSensitivity;
use crate::model::geom::{exp_twist, so3_right_jacobian_inverse};
use crate::model::param::{ParamInfo, Quantity};
use crate::model::perturbation::Perturbation;
use crate::model::tree::KinematicTree;
use crate::robot::{Conditions, Robot, RobotWorkspace};
use rayon::prelude::*;

/// The pose of the robot's frame link (`[measurement] frame_link`) in the root frame of
/// the kinematics last evaluated into `ws`; the identity without one.
pub(super) fn frame_link_pose(
    robot: &Robot,
    tree: &KinematicTree,
    ws: &crate::robot::RobotWorkspace,
) -> Isometry3<f64> {
    match robot.frame_link() {
        Some(b) => ws.frames.body[b] * tree.bodies()[b].convention_frame,
        None => Isometry3::identity(),
    }
}

/// The model's point and marker rotation at every sample, evaluated in parallel (each sample
/// on its own, so the result does not depend on the thread count).
pub(super) fn evaluate(robot: &Robot, d: &Decoded, samples: &[Sample]) -> Evaluation {
    let (world, (marker_rot, rotation)) = samples
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
                let frame = frame_link_pose(robot, &d.tree, ws).inverse() * ws.frames.point[s.point];
                (frame.translation.vector, (rot, frame.rotation))
            },
        )
        .unzip();
    Evaluation {
        world,
        marker_rot,
        rotation,
    }
}

/// `log(R_measᵀ R̂)` of sample `i` (rad, in the model's frame): the turn from the measured
/// orientation to the modelled one.
fn orientation_residual(d: &Decoded, e: &Evaluation, s: &Sample, i: usize) -> Vector3<f64> {
    let measured = s.orientation.unwrap_or_default();
    (measured.inverse() * d.frames[s.station].rotation * e.rotation[i]).scaled_axis()
}

/// The model's points `world` (robot base frame) seen from each sample's station.
pub(super) fn to_meas(frames: &[Isometry3<f64>], samples: &[Sample], world: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
    world
        .iter()
        .zip(samples)
        .map(|(p, s)| frames[s.station].transform_point(&(*p).into()).coords)
        .collect()
}

impl Problem<'_> {
    pub(super) fn predict(&self, theta: &[f64]) -> Result<(Decoded, Evaluation, Vec<Vector3<f64>>)> {
        let d = self.space.decode(self.robot, theta)?;
        let e = evaluate(self.robot, &d, self.samples);
        let meas = to_meas(&d.frames, self.samples, &e.world);
        Ok((d, e, meas))
    }

    /// ½χ² of `stage` with the priors of `free` centred at `theta0`: what Levenberg–Marquardt
    /// minimises.
    pub(super) fn cost(&self, stage: &Stage, theta0: &[f64], free: &[usize]) -> f64 {
        let r = self.residuals(&stage.d, &stage.e);
        self.cost_of(&stage.theta, theta0, free, &r)
    }

    pub(super) fn cost_of(&self, theta: &[f64], theta0: &[f64], free: &[usize], r: &DVector<f64>) -> f64 {
        let prior: f64 = free
            .iter()
            .map(|&k| ((theta[k] - theta0[k]) / self.space.params[k].info.sigma).powi(2))
            .sum();
        0.5 * (r.norm_squared() + prior)
    }

    /// The RMS of `stage`'s position residuals (3-D, or a plane's height) over what the noise
    /// alone gives (√3 σ, or σ).
    pub(super) fn rms_over_noise(&self, stage: &Stage) -> f64 {
        let r = self.residuals(&stage.d, &stage.e);
        let n = self.position_rows();
        (r.rows(0, n).norm_squared() / n.max(1) as f64).sqrt()
    }

    /// Measurement residuals, whitened by their noise: `(p̂ − p) / σ`, three per sample (`p`
    /// its fixed point's position for fixed-point samples), then `log(R_measᵀ R̂) / σ_rot`,
    /// three per oriented sample, then `(‖p_a − p_b‖ − d) / σ_d` per known distance.
    ///
    /// Plane contacts give their height above the plane `/ σ` (when constrained) as the
    /// position block and their constrained tilts `/ σ_rot` as the orientation block.
    pub(super) fn residuals(&self, d: &Decoded, e: &Evaluation) -> DVector<f64> {
        let predicted = to_meas(&d.frames, self.samples, &e.world);
        let gaps: Vec<Option<PlaneGap>> = match self.constraints {
            Some(_) => (0..self.samples.len())
                .map(|i| self.plane[i].map(|g| self.plane_gap(d, e, i, g)))
                .collect(),
            None => Vec::new(),
        };
        let positions = predicted.iter().enumerate().flat_map(|(i, p)| {
            let r = match gaps.get(i) {
                Some(Some(gap)) => Vector3::new(gap.height, 0.0, 0.0) / self.sigma,
                _ => (p - self.target(d, i, p)) / self.sigma,
            };
            [r.x, r.y, r.z].into_iter().take(self.position_range(i).len())
        });
        let orientations = self.oriented.iter().enumerate().flat_map(|(k, &i)| {
            let r = match (gaps.get(i), &self.constraints) {
                (Some(Some(gap)), Some(c)) => {
                    let t = gap.tilts(c, self.sigma_rot);
                    Vector3::new(t[0], t[1], 0.0)
                }
                _ => orientation_residual(d, e, &self.samples[i], i) / self.sigma_rot,
            };
            [r.x, r.y, r.z].into_iter().take(self.turn_range(k).len())
        });
        let distances = (0..self.distances.len()).map(|k| {
            let known = &self.distances[k];
            (self.distance(d, k).0 - known.metres) / known.sigma
        });
        let mut r = DVector::from_iterator(self.n_residuals(), positions.chain(orientations).chain(distances));
        self.weigh_rows(|row, w| r[row] *= w);
        r
    }

    /// Statistics of the orientation residuals (`None` without pose samples).
    pub(super) fn orientation_stats(&self, d: &Decoded, e: &Evaluation) -> Option<AngleStats> {
        // The poses' alone: a plane contact's tilts have their own figures.
        let angles: Vec<f64> = (self.oriented.iter())
            .filter(|&&i| self.plane[i].is_none())
            .map(|&i| orientation_residual(d, e, &self.samples[i], i).norm())
            .collect();
        (!angles.is_empty()).then(|| AngleStats::from_angles(&angles))
    }

    /// How each Jacobian column of `free` is computed at `theta`.
    pub(super) fn column_plans(
        &self,
        theta: &[f64],
        d: &Decoded,
        free: &[usize],
        form: JacobianForm<'_>,
    ) -> Result<Vec<ColumnPlan>> {
        let space = self.space;
        free.iter()
            .map(|&k| {
                let p = &space.params[k];
                Ok(match p.group {
                    ParamGroup::Marker(i) => ColumnPlan::Marker {
                        point: self.robot.markers()[i],
                        axis: (k - space.marker_offset) % space.marker_dofs,
                    },
                    ParamGroup::FixedPoint(index) => ColumnPlan::FixedPoint {
                        index,
                        axis: (k - space.fixed_point_offset) % 3,
                    },
                    ParamGroup::Plane(index) => {
                        // ∂(origin, normal)/∂parameter of T_nom · Tz(h) · Ry(pitch) Rx(roll).
                        let o = space.plane_offset + 3 * index;
                        let (roll, pitch) = (theta[o + 1], theta[o + 2]);
                        let nominal = space.plane_nominal[index];
                        let (sr, cr, sp, cp) = (roll.sin(), roll.cos(), pitch.sin(), pitch.cos());
                        let (origin, normal) = match k - o {
                            0 => (nominal.rotation * Vector3::z(), Vector3::zeros()),
                            1 => (Vector3::zeros(), Vector3::new(-sr * sp, -cr, -sr * cp)),
                            _ => (Vector3::zeros(), Vector3::new(cr * cp, 0.0, -cr * sp)),
                        };
                        ColumnPlan::Plane {
                            index,
                            origin,
                            normal: nominal.rotation * normal,
                        }
                    }
                    ParamGroup::Base => {
                        let (mut t, h) = step(theta, k, p);
                        t[k] += h;
                        let station = space.station_of(k);
                        ColumnPlan::Base {
                            station,
                            from: space.base_pose(theta, station),
                            to: space.base_pose(&t, station),
                            h,
                        }
                    }
                    ParamGroup::ErrorModel(i) => {
                        let (_, h) = step(theta, k, p);
                        let mut errors = d.errors.clone();
                        errors[i][k - space.error_offsets[i]] += h;
                        // A sensor's mounting turns the readings every model and load sees.
                        let model = &self.robot.error_models()[i];
                        if model.adjusts_loads() || model.sensor_mounting(&d.errors[i]).is_some() {
                            ColumnPlan::Loads { errors, h }
                        } else {
                            ColumnPlan::Model { model: i, errors, h }
                        }
                    }
                    ParamGroup::Geometry => {
                        let (mut t, h) = step(theta, k, p);
                        t[k] += h;
                        let deformed = matches!(form, JacobianForm::Exact) && self.robot.deforms_at(&d.errors);
                        // A parameter that moves one placement alone is a twist at that joint:
                        // the same column as the stepped tree's, without building it.
                        let moved = (!deformed && k < space.n_chain)
                            .then(|| self.robot.chain().placement_moved_by(&t[..space.n_chain], k))
                            .flatten();
                        match moved {
                            Some((j, placed)) => ColumnPlan::Twists {
                                joints: placement_twist(&d.tree.joints()[j].placement, &placed, h)
                                    .map(|xi| (j, xi))
                                    .into_iter()
                                    .collect(),
                                points: Vec::new(),
                                deformation: None,
                            },
                            None => geometry_plan(&d.tree, space.tree(self.robot, &t)?, h, deformed),
                        }
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
        form: JacobianForm<'_>,
    ) -> Result<DMatrix<f64>> {
        Ok(self.jacobian_parts(theta, d, e, free, form)?.0)
    }

    /// [`jacobian`](Self::jacobian) and, in the exact form, what the deformation's change adds
    /// to the geometry columns (zero elsewhere; before the rows' robust weights): the exact
    /// Jacobian minus the held one. That
    /// part is about 1e-3 of the columns and changes slowly, so a fit reuses it
    /// ([`HeldPlus`](JacobianForm::HeldPlus)) rather than re-evaluate the models for every
    /// geometry column, pose and iteration.
    pub(super) fn jacobian_parts(
        &self,
        theta: &[f64],
        d: &Decoded,
        e: &Evaluation,
        free: &[usize],
        form: JacobianForm<'_>,
    ) -> Result<(DMatrix<f64>, Option<DMatrix<f64>>)> {
        let plans = self.column_plans(theta, d, free, form)?;
        let ncols = plans.len();
        let deformed = plans.iter().any(|p| {
            matches!(
                p,
                ColumnPlan::Twists {
                    deformation: Some(_),
                    ..
                }
            )
        });
        let rows: Vec<(Vec<f64>, Vec<f64>)> = (0..self.samples.len())
            .into_par_iter()
            .map_init(
                || RowBuffers::new(self.robot, d),
                |b, s_idx| self.sample_rows(&plans, d, e, s_idx, deformed, b),
            )
            .collect();
        let (mut jac, part) = if deformed {
            let (rows, parts): (Vec<_>, Vec<_>) = rows.into_iter().unzip();
            (self.assemble(&rows, ncols), Some(self.assemble(&parts, ncols)))
        } else {
            let rows: Vec<_> = rows.into_iter().map(|(row, _)| row).collect();
            (self.assemble(&rows, ncols), None)
        };
        if let (JacobianForm::HeldPlus(extra), None) = (form, &part) {
            jac += extra;
        }
        self.distance_rows(d, &plans, &mut jac);
        self.weigh_rows(|row, w| jac.row_mut(row).iter_mut().for_each(|v| *v *= w));
        Ok((jac, part))
    }

    /// Known distances' rows: ∂‖p_a − p_b‖/∂p_a = u, ∂/∂p_b = −u, u the unit vector from b to
    /// a.
    fn distance_rows(&self, d: &Decoded, plans: &[ColumnPlan], jac: &mut DMatrix<f64>) {
        let r0 = self.position_rows() + self.turn_rows();
        for (k, known) in self.distances.iter().enumerate() {
            let (_, u) = self.distance(d, k);
            for (c, plan) in plans.iter().enumerate() {
                if let ColumnPlan::FixedPoint { index, axis } = *plan {
                    let sign = if index == known.a {
                        1.0
                    } else if index == known.b {
                        -1.0
                    } else {
                        continue;
                    };
                    jac[(r0 + k, c)] = sign * u[axis] / known.sigma;
                }
            }
        }
    }

    /// Sample `s_idx`'s rows of the Jacobian (per column its position then orientation
    /// entries) and, when `deformed`, the part the deformation's change adds to them.
    fn sample_rows(
        &self,
        plans: &[ColumnPlan],
        d: &Decoded,
        e: &Evaluation,
        s_idx: usize,
        deformed: bool,
        b: &mut RowBuffers,
    ) -> (Vec<f64>, Vec<f64>) {
        let view = self.sample_view(d, e, s_idx, b);
        let ncols = plans.len();
        let mut out = SampleRows {
            row: vec![0.0; view.width * ncols],
            part: vec![0.0; if deformed { view.width * ncols } else { 0 }],
        };
        for (c, plan) in plans.iter().enumerate() {
            if let Some((dp_meas, dw_meas)) = self.column_change(plan, c, d, &view, b, &mut out) {
                view.write(self, &mut out.row, c, dp_meas, dw_meas);
            }
        }
        (out.row, out.part)
    }

    /// Evaluates the full model at sample `s_idx` into `b` and gathers what its rows are
    /// built from.
    fn sample_view<'v>(&self, d: &'v Decoded, e: &Evaluation, s_idx: usize, b: &mut RowBuffers) -> SampleView<'v> {
        let s = &self.samples[s_idx];
        let n_models = self.robot.error_models().len();
        let cond = Conditions::of(s);
        let ws = &mut b.ws;
        self.robot.forward_with_into(&d.tree, &d.errors, &s.q, cond, ws);
        // Root-frame changes seen from the measurement frame (through the frame link's, when
        // the measurements are expressed in one).
        let link = frame_link_pose(self.robot, &d.tree, ws);
        let r_meas = (d.frames[s.station].rotation * link.rotation.inverse())
            .to_rotation_matrix()
            .into_inner();
        for (i, bp) in b.base_perts.iter_mut().enumerate() {
            bp.clear();
            self.robot.model_perturbation_into(i, &d.tree, &d.errors[i], s, ws, bp);
        }
        if n_models > 0 {
            b.sensitivity.update(&d.tree, &ws.frames, &ws.perturbation, s.point);
        }
        let body = d.tree.points()[s.point].body;
        let support = d.tree.support(body);
        // The joints that move the frame link move the measured point the other way.
        let link_support = self.robot.frame_link().map_or(&[][..], |b| d.tree.support(b));
        // Geometry moves a joint's placement, which the deformation's twist follows: its twist
        // acts at the placed frame before that twist (and a point's before its own), not at
        // the deformed one.
        let (frames, deformation) = (&ws.frames, &ws.perturbation);
        for &j in support.iter().chain(link_support) {
            b.placed[j] = frames.joint_frame[j];
            if n_models > 0 {
                b.placed[j] *= exp_twist(&deformation.joint_twist[j]).inverse();
            }
        }
        let point_frame = if n_models > 0 {
            frames.point[s.point] * exp_twist(&deformation.point_twist[s.point]).inverse()
        } else {
            frames.point[s.point]
        };
        let oriented = self.oriented.binary_search(&s_idx).ok();
        // Rows of the orientation block: J_r⁻¹(r) R̂ᵀ per unit turn of the model (measurement
        // frame), so a turn maps to the change of log(R_measᵀ R̂).
        let turn_map = oriented.filter(|_| self.plane[s_idx].is_none()).map(|_| {
            let model = d.frames[s.station].rotation * e.rotation[s_idx];
            let r = orientation_residual(d, e, s, s_idx);
            so3_right_jacobian_inverse(&r) * model.inverse().to_rotation_matrix().into_inner() / self.sigma_rot
        });
        // A plane contact's residuals and the maps from the point's change to theirs.
        let gap = match (self.plane[s_idx], &self.constraints) {
            (Some(g), Some(_)) => Some(self.plane_gap(d, e, s_idx, g)),
            _ => None,
        };
        let tw = oriented.map_or(0, |k| self.turn_range(k).len());
        let pw = self.position_range(s_idx).len();
        SampleView {
            s_idx,
            point: s.point,
            world: e.world[s_idx],
            marker_rot: e.marker_rot[s_idx],
            cond,
            link,
            before: link.inverse() * frames.point[s.point],
            r_meas,
            support,
            link_support,
            p: frames.point[s.point].translation.vector,
            point_frame,
            oriented: oriented.is_some(),
            turn_map,
            gap,
            pw,
            tw,
            width: pw + tw,
        }
    }

    /// The change of the sample's point position and orientation (measurement frame) per unit
    /// of column `c`'s parameter; `None` when the column does not move it or has written its
    /// rows itself (a plane's). The exact form's deformation share is also written to `part`.
    fn column_change(
        &self,
        plan: &ColumnPlan,
        c: usize,
        d: &Decoded,
        v: &SampleView<'_>,
        b: &mut RowBuffers,
        out: &mut SampleRows,
    ) -> Option<(Vector3<f64>, Vector3<f64>)> {
        let s = &self.samples[v.s_idx];
        let (r_meas, cond) = (v.r_meas, v.cond);
        let RowBuffers {
            ws,
            ws_fd,
            base_perts,
            scratch,
            stepped,
            placed,
            sensitivity,
        } = b;
        Some(match plan {
            ColumnPlan::Marker { point, axis } => {
                if *point != s.point {
                    return None;
                }
                if *axis < 3 {
                    (r_meas * v.marker_rot.column(*axis), Vector3::zeros())
                } else {
                    // A turn about the point's own axis, before its deformation.
                    let axis = v.point_frame.rotation * Vector3::ith(*axis - 3, 1.0);
                    (Vector3::zeros(), r_meas * axis)
                }
            }
            // The target moves, not the model: minus the axis.
            ColumnPlan::FixedPoint { index, axis } => {
                if self.fixed[v.s_idx] != Some(*index) {
                    return None;
                }
                (-Vector3::ith(*axis, 1.0), Vector3::zeros())
            }
            // The plane moves: its rows directly, the model unchanged.
            ColumnPlan::Plane { index, origin, normal } => {
                let (Some(gap), Some(cons)) = (&v.gap, &self.constraints) else {
                    return None;
                };
                if self.plane[v.s_idx] != Some(*index) {
                    return None;
                }
                let (pw, width) = (v.pw, v.width);
                if pw == 1 {
                    out.row[width * c] = (normal.dot(&gap.offset) - gap.normal.dot(origin)) / self.sigma;
                }
                let t = gap.tilt_rows(cons, &(gap.contact.inverse() * normal), self.sigma_rot);
                out.row[width * c + pw..width * (c + 1)].copy_from_slice(&t[..v.tw]);
                return None;
            }
            ColumnPlan::Base { station, .. } if *station != s.station => return None,
            ColumnPlan::Base { from, to, h, .. } => (
                (to.transform_point(&v.world.into()) - from.transform_point(&v.world.into())) / *h,
                (to.rotation * from.rotation.inverse()).scaled_axis() / *h,
            ),
            ColumnPlan::Twists {
                joints,
                points,
                deformation,
            } => {
                let (mut dp, mut dw) = v.twists_effect(joints, points, placed);
                if let Some((tree, stepped_joints, h)) = deformation {
                    self.robot.deformation_restepped_into(
                        tree,
                        &d.errors,
                        &s.q,
                        cond,
                        &ws.rigid,
                        stepped_joints,
                        ws_fd,
                    );
                    scratch.set_difference(&ws_fd.perturbation, &ws.perturbation, 1.0 / *h);
                    let dp_def = sensitivity.effect(scratch);
                    // The deformation's turn has no cheap map: the full model differenced, on
                    // pose samples only.
                    let dw_def = if v.oriented {
                        self.robot.forward_with_into(tree, &d.errors, &s.q, cond, ws_fd);
                        v.moved(self.robot, ws_fd, tree, *h).1 - dw
                    } else {
                        Vector3::zeros()
                    };
                    v.write(self, &mut out.part, c, r_meas * dp_def, r_meas * dw_def);
                    dp += dp_def;
                    dw += dw_def;
                }
                (r_meas * dp, r_meas * dw)
            }
            ColumnPlan::Loads { errors, h } => {
                // A changed load changes what every elastic model does.
                self.robot.forward_with_into(&d.tree, errors, &s.q, cond, ws_fd);
                let (dp, dw) = v.moved(self.robot, ws_fd, &d.tree, *h);
                (r_meas * dp, r_meas * dw)
            }
            ColumnPlan::Finite { tree, h } => {
                self.robot.forward_with_into(tree, &d.errors, &s.q, cond, ws_fd);
                let (dp, dw) = v.moved(self.robot, ws_fd, tree, *h);
                (r_meas * dp, r_meas * dw)
            }
            ColumnPlan::Model { model, errors, h } => {
                stepped.clear();
                self.robot
                    .model_perturbation_into(*model, &d.tree, &errors[*model], s, ws, stepped);
                scratch.set_difference(stepped, &base_perts[*model], 1.0 / *h);
                let dw = if v.oriented {
                    self.robot.forward_with_into(&d.tree, errors, &s.q, cond, ws_fd);
                    v.moved(self.robot, ws_fd, &d.tree, *h).1
                } else {
                    Vector3::zeros()
                };
                (r_meas * sensitivity.effect(scratch), r_meas * dw)
            }
        })
    }

    /// The Jacobian's sample rows (per sample: per column its position then orientation
    /// entries) placed as the residuals are: position rows in sample order, then the
    /// orientation rows of the oriented samples. Distance rows are left zero.
    fn assemble(&self, rows: &[Vec<f64>], ncols: usize) -> DMatrix<f64> {
        let mut jac = DMatrix::zeros(self.n_residuals(), ncols);
        for (s_idx, row) in rows.iter().enumerate() {
            let positions = self.position_range(s_idx);
            let turns = (self.oriented.binary_search(&s_idx).ok()).map_or(0..0, |k| self.turn_range(k));
            let (pw, tw) = (positions.len(), turns.len());
            let width = pw + tw;
            for c in 0..ncols {
                for a in 0..pw {
                    jac[(positions.start + a, c)] = row[width * c + a];
                }
                for a in 0..tw {
                    jac[(turns.start + a, c)] = row[width * c + pw + a];
                }
            }
        }
        jac
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
    let twist = |a: &Isometry3<f64>, b: &Isometry3<f64>| placement_twist(a, b, h);
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

/// The twist (per unit step `h`, in `a`'s frame) that takes placement `a` to `b`; none when
/// they are equal.
fn placement_twist(a: &Isometry3<f64>, b: &Isometry3<f64>, h: f64) -> Option<Vector6<f64>> {
    let rel = a.inverse() * b;
    let v = rel.translation.vector / h;
    let w = rel.rotation.scaled_axis() / h;
    let xi = Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z);
    (xi != Vector6::zeros()).then_some(xi)
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
            fixed_point: None,
            plane: None,
            sensors: Default::default(),
            station: 0,
            position_std: None,
        })
        .collect()
}

/// [`identification_jacobian`] at the configurations, points and conditions (payload,
/// temperature) of `samples`, the rows as calibration lays them out: each sample's position
/// rows (three, or a plane contact's height) in sample order, then the orientation rows of the
/// samples that have them (a pose's three, a contact's tilts), then one per known distance;
/// their measured values are not used.
pub fn samples_jacobian(robot: &Robot, samples: &[Sample], identify: &[String]) -> Result<(DMatrix<f64>, Vec<String>)> {
    let (jac, names, _) = jacobian_and_sample_rows(robot, samples, identify)?;
    Ok((jac, names))
}

/// [`samples_jacobian`] with each sample's rows together, in sample order, and how many rows
/// each sample has: what choosing among candidate samples needs. Rows of no sample (known
/// distances) are left out.
pub fn samples_jacobian_by_sample(
    robot: &Robot,
    samples: &[Sample],
    identify: &[String],
) -> Result<(DMatrix<f64>, Vec<String>, Vec<usize>)> {
    let (jac, names, rows) = jacobian_and_sample_rows(robot, samples, identify)?;
    let order: Vec<usize> = rows.iter().flatten().copied().collect();
    Ok((
        jac.select_rows(order.iter()),
        names,
        rows.iter().map(Vec::len).collect(),
    ))
}

/// A Jacobian, its columns' parameter names and each sample's rows.
type SampleJacobian = (DMatrix<f64>, Vec<String>, Vec<Vec<usize>>);

/// [`samples_jacobian`] and the rows of each sample.
fn jacobian_and_sample_rows(robot: &Robot, samples: &[Sample], identify: &[String]) -> Result<SampleJacobian> {
    for s in samples {
        robot.tree().check_q(&s.q)?;
    }
    let space = ParameterSpace::for_samples(robot, samples);
    let selected = space.select(robot, identify)?;
    let problem = Problem::new(robot, &space, samples, Noise::UNIT);
    let theta = problem.start()?;
    let (d, e, _) = problem.predict(&theta)?;
    let jac = problem.jacobian(&theta, &d, &e, &selected, JacobianForm::Exact)?;
    Ok((
        jac,
        selected.iter().map(|&k| space.params[k].info.name.clone()).collect(),
        (0..samples.len()).map(|i| problem.rows_of_sample(i)).collect(),
    ))
}

/// Per-thread buffers of the Jacobian's sample rows: the model at the sample, the model
/// re-evaluated for a column, the error models' own perturbations, and the placed frames.
struct RowBuffers {
    ws: RobotWorkspace,
    ws_fd: RobotWorkspace,
    base_perts: Vec<Perturbation>,
    scratch: Perturbation,
    stepped: Perturbation,
    placed: Vec<Isometry3<f64>>,
    sensitivity: PointSensitivity,
}

impl RowBuffers {
    fn new(robot: &Robot, d: &Decoded) -> Self {
        let pert = Perturbation::zeros(&d.tree);
        RowBuffers {
            ws: robot.workspace(),
            ws_fd: robot.workspace(),
            base_perts: vec![pert.clone(); robot.error_models().len()],
            scratch: pert.clone(),
            stepped: pert,
            placed: vec![Isometry3::identity(); d.tree.joints().len()],
            sensitivity: PointSensitivity::default(),
        }
    }
}

/// One sample's Jacobian rows (per column its position then orientation entries) and the
/// part of them the deformation's change adds (empty unless the exact form has one).
struct SampleRows {
    row: Vec<f64>,
    part: Vec<f64>,
}

/// One sample's model at the fit's parameters: what its Jacobian rows are built from.
struct SampleView<'v> {
    s_idx: usize,
    /// The measured point.
    point: usize,
    cond: Conditions,
    /// The modelled point (robot base frame) and the marker's rotation.
    world: Vector3<f64>,
    marker_rot: Matrix3<f64>,
    /// The frame link's pose, and the point's relative to it.
    link: Isometry3<f64>,
    before: Isometry3<f64>,
    /// Root-frame directions seen from the measurement frame.
    r_meas: Matrix3<f64>,
    /// The joints moving the point, and those moving the frame link.
    support: &'v [usize],
    link_support: &'v [usize],
    /// The point (root frame) and its frame before its own deformation.
    p: Vector3<f64>,
    point_frame: Isometry3<f64>,
    oriented: bool,
    turn_map: Option<Matrix3<f64>>,
    gap: Option<PlaneGap>,
    /// Rows per sample: position, turn, both.
    pw: usize,
    tw: usize,
    width: usize,
}

impl SampleView<'_> {
    /// The point's move (root frame) when frame `f` moves by twist `xi` (its own frame).
    fn effect_at(&self, f: &Isometry3<f64>, xi: &Vector6<f64>) -> Vector3<f64> {
        let v = f.rotation * xi.fixed_rows::<3>(0);
        let w = f.rotation * xi.fixed_rows::<3>(3);
        v + w.cross(&(self.p - f.translation.vector))
    }

    /// The point's move and turn (root frame) from geometry twists at the joints' placed
    /// frames (`placed`) and at the point.
    fn twists_effect(
        &self,
        joints: &[(usize, Vector6<f64>)],
        points: &[(usize, Vector6<f64>)],
        placed: &[Isometry3<f64>],
    ) -> (Vector3<f64>, Vector3<f64>) {
        let mut dp = Vector3::zeros();
        let mut dw = Vector3::zeros();
        for (j, xi) in joints {
            // +1 on the point's path, −1 on the frame link's, 0 on both.
            let sign =
                f64::from(u8::from(self.support.contains(j))) - f64::from(u8::from(self.link_support.contains(j)));
            if sign != 0.0 {
                dp += sign * self.effect_at(&placed[*j], xi);
                dw += sign * (placed[*j].rotation * xi.fixed_rows::<3>(3));
            }
        }
        for (i, xi) in points {
            if *i == self.point {
                dp += self.effect_at(&self.point_frame, xi);
                dw += self.point_frame.rotation * xi.fixed_rows::<3>(3);
            }
        }
        (dp, dw)
    }

    /// The change of the point's pose relative to the frame link (root-aligned, as `r_meas`
    /// expects) per unit step `h`, from the full model re-evaluated into `ws_fd`.
    fn moved(
        &self,
        robot: &Robot,
        ws_fd: &RobotWorkspace,
        tree: &KinematicTree,
        h: f64,
    ) -> (Vector3<f64>, Vector3<f64>) {
        let stepped = frame_link_pose(robot, tree, ws_fd);
        let after = stepped.inverse() * ws_fd.frames.point[self.point];
        let dp = self.link.rotation * (after.translation.vector - self.before.translation.vector) / h;
        let dw = self.link.rotation * (after.rotation * self.before.rotation.inverse()).scaled_axis() / h;
        (dp, dw)
    }

    /// Writes column `c` of this sample's rows from the change of the point's position and
    /// orientation (measurement frame).
    fn write(&self, problem: &Problem<'_>, row: &mut [f64], c: usize, dp_meas: Vector3<f64>, dw_meas: Vector3<f64>) {
        let (pw, tw, width) = (self.pw, self.tw, self.width);
        if let (Some(gap), Some(cons)) = (&self.gap, &problem.constraints) {
            if pw == 1 {
                row[width * c] = gap.normal.dot(&dp_meas) / problem.sigma;
            }
            // A turn of the contact turns the normal seen from it the other way.
            let dm = gap.contact.inverse() * gap.normal.cross(&dw_meas);
            let t = gap.tilt_rows(cons, &dm, problem.sigma_rot);
            row[width * c + pw..width * (c + 1)].copy_from_slice(&t[..tw]);
            return;
        }
        for a in 0..3 {
            row[width * c + a] = dp_meas[a] / problem.sigma;
        }
        if let Some(map) = &self.turn_map {
            let dr = map * dw_meas;
            for a in 0..3 {
                row[width * c + 3 + a] = dr[a];
            }
        }
    }
}
