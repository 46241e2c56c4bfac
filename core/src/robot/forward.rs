//! Evaluating the full model (chain + error models) of a built robot: frames, deformations,
//! gravity loads and measured positions, into a reusable [`RobotWorkspace`].

use nalgebra::Vector3;

use crate::error::Result;
use crate::kinematics::sensor::{GravityReading, GravitySensor, SensorReadings};
use crate::kinematics::subtree_loads::SubtreeLoads;
use crate::kinematics::workspace::TreeWorkspace;
use crate::model::mass::{MassModel, Payload};
use crate::model::perturbation::Perturbation;
use crate::model::tree::KinematicTree;
use crate::plugin::StaticState;
use crate::robot::{Conditions, Robot, RobotWorkspace};

impl Robot {
    /// Buffers sized for this robot.
    pub fn workspace(&self) -> RobotWorkspace {
        RobotWorkspace {
            rigid: TreeWorkspace::new(&self.tree),
            perturbation: Perturbation::zeros(&self.tree),
            frames: TreeWorkspace::new(&self.tree),
            mass: self.mass.clone(),
            loads: SubtreeLoads::default(),
            own_mass: true,
            gravity: self.gravity,
            sensors: SensorReadings::default(),
        }
    }

    /// Forward kinematics of the full model (chain + error models) into `ws.frames`.
    /// `temperature` (°C) is passed to models that use it.
    pub fn forward_into(&self, q: &[f64], temperature: Option<f64>, ws: &mut RobotWorkspace) {
        let conditions = Conditions {
            temperature,
            ..Conditions::default()
        };
        self.forward_under_into(q, conditions, ws);
    }

    /// [`forward_into`](Robot::forward_into) under all of `conditions` (temperature, payload,
    /// the sensors' readings).
    pub fn forward_under_into(&self, q: &[f64], conditions: Conditions, ws: &mut RobotWorkspace) {
        self.forward_with_into(&self.tree, &self.error_values, q, conditions, ws);
    }

    /// Forward kinematics of the full model with other parameter values than the robot's own:
    /// `tree` from [`tree_for`](Robot::tree_for) and one value list per error model (what
    /// calibration varies). A payload in `conditions` replaces the file's payload mass.
    pub fn forward_with_into(
        &self,
        tree: &KinematicTree,
        error_values: &[Vec<f64>],
        q: &[f64],
        conditions: Conditions,
        ws: &mut RobotWorkspace,
    ) {
        if self.error_models.is_empty() {
            tree.forward_into(q, &mut ws.rigid);
            ws.frames.clone_from(&ws.rigid);
            return;
        }
        self.deformation_into(tree, error_values, q, conditions, ws);
        tree.forward_perturbed_from_rigid_into(q, &ws.perturbation, &ws.rigid, &mut ws.frames);
    }

    /// The first half of [`forward_with_into`](Robot::forward_with_into): the rigid frames
    /// into `ws.rigid` and the error models' deformation into `ws.perturbation`, without the
    /// deformed frames (`ws.frames` is left as it was).
    pub fn deformation_into(
        &self,
        tree: &KinematicTree,
        error_values: &[Vec<f64>],
        q: &[f64],
        conditions: Conditions,
        ws: &mut RobotWorkspace,
    ) {
        tree.forward_into(q, &mut ws.rigid);
        self.deformation_at_rigid_into(tree, error_values, q, conditions, ws);
    }

    /// [`deformation_into`](Robot::deformation_into) of a tree that differs from the one
    /// `prefix` evaluated at the same `q` only in the placements of the joints `stepped` and in
    /// its points (see [`KinematicTree::forward_restepped_into`]); the same bits.
    #[allow(clippy::too_many_arguments)]
    pub fn deformation_restepped_into(
        &self,
        tree: &KinematicTree,
        error_values: &[Vec<f64>],
        q: &[f64],
        conditions: Conditions,
        prefix: &TreeWorkspace,
        stepped: &[usize],
        ws: &mut RobotWorkspace,
    ) {
        tree.forward_restepped_into(q, prefix, stepped, &mut ws.rigid);
        self.deformation_at_rigid_into(tree, error_values, q, conditions, ws);
    }

    /// The error models' deformation at the rigid frames already in `ws.rigid`.
    fn deformation_at_rigid_into(
        &self,
        tree: &KinematicTree,
        error_values: &[Vec<f64>],
        q: &[f64],
        conditions: Conditions,
        ws: &mut RobotWorkspace,
    ) {
        ws.perturbation.clear();
        // The readings once: the loads' gravity and the models' state share them.
        ws.sensors = self.sensor_readings(conditions, error_values);
        let (own_mass, gravity) = self.loads_with(conditions, &ws.sensors, tree, &ws.rigid, error_values, &mut ws.mass);
        ws.own_mass = own_mass;
        ws.gravity = gravity;
        let mass = if own_mass { &self.mass } else { &ws.mass };
        ws.loads.update(tree, &ws.rigid, mass);
        let state = StaticState {
            q,
            tree,
            frames: &ws.rigid,
            mass,
            loads: &ws.loads,
            gravity,
            temperature: conditions.temperature,
            sensors: ws.sensors,
        };
        for (m, v) in self.error_models.iter().zip(error_values) {
            if !m.is_inactive(v) {
                m.perturb(&state, v, &mut ws.perturbation);
            }
        }
    }

    /// Whether some error model deforms the robot at `error_values` (one list per model; see
    /// [`ErrorModel::is_inactive`]).
    pub fn deforms_at(&self, error_values: &[Vec<f64>]) -> bool {
        self.error_models
            .iter()
            .zip(error_values)
            .any(|(m, v)| !m.is_inactive(v))
    }

    /// The loads under `conditions` with the points of `tree` and error-model `values`:
    /// whether the mass model is the robot's own (otherwise the one written into `scratch`:
    /// a payload applied, or load-adjusting models' payload mass) and the gravity (base
    /// frame; a measured direction carried there by the rigid frames `frames` of `tree`),
    /// load-adjusting models applied in order.
    pub fn loads_into(
        &self,
        conditions: Conditions,
        tree: &KinematicTree,
        frames: &TreeWorkspace,
        error_values: &[Vec<f64>],
        scratch: &mut MassModel,
    ) -> (bool, Vector3<f64>) {
        let readings = self.sensor_readings(conditions, error_values);
        self.loads_with(conditions, &readings, tree, frames, error_values, scratch)
    }

    /// [`loads_into`](Self::loads_into) with the sensor readings of `conditions` already
    /// turned by their mountings ([`sensor_readings`](Self::sensor_readings)).
    fn loads_with(
        &self,
        conditions: Conditions,
        readings: &SensorReadings,
        tree: &KinematicTree,
        frames: &TreeWorkspace,
        error_values: &[Vec<f64>],
        scratch: &mut MassModel,
    ) -> (bool, Vector3<f64>) {
        let adjusting = self.error_models.iter().any(|m| m.adjusts_loads());
        let own = self.mass_is_own(conditions, tree);
        let gravity = self.gravity_of(readings, tree, frames);
        if !adjusting {
            if !own {
                self.mass_under(conditions, tree, scratch);
            }
            return (own, gravity);
        }
        if own {
            scratch.clone_from(&self.mass);
        } else {
            self.mass_under(conditions, tree, scratch);
        }
        let declared = scratch.payload.as_ref().map_or(0.0, |p| p.mass);
        // A load-adjusting model starts from the measured gravity: `base_tilt` then turns it by
        // a constant angle, the sensor's misalignment with the base (see its documentation).
        let mut loads = crate::plugin::Loads {
            gravity,
            payload_mass: declared,
        };
        for (m, v) in self.error_models.iter().zip(error_values) {
            m.adjust_loads(v, &mut loads);
        }
        if loads.payload_mass != declared {
            let (body, com) = self.payload_site(tree);
            scratch.payload.get_or_insert(Payload { mass: 0.0, body, com }).mass = loads.payload_mass;
        }
        (false, loads.gravity)
    }

    /// Gravity in the base frame (m/s²) under `conditions`: the robot file's, or its magnitude
    /// along the gravity sensor's reading (its mounting corrected by error-model `values`)
    /// carried to the base frame by the rigid frames `frames` of `tree` (the sensor's link
    /// where the row's joint values put it).
    pub fn gravity_under(
        &self,
        conditions: Conditions,
        tree: &KinematicTree,
        frames: &TreeWorkspace,
        error_values: &[Vec<f64>],
    ) -> Vector3<f64> {
        self.gravity_of(&self.sensor_readings(conditions, error_values), tree, frames)
    }

    /// [`gravity_under`](Self::gravity_under) from readings already turned by their mountings.
    fn gravity_of(&self, readings: &SensorReadings, tree: &KinematicTree, frames: &TreeWorkspace) -> Vector3<f64> {
        match self.gravity_sensor.and_then(|k| readings.get(k)) {
            Some(reading) => self.gravity.norm() * reading.in_base(tree, frames),
            None => self.gravity,
        }
    }

    /// The sensor readings of `conditions` turned from each sensor's frame into its link's by
    /// the mounting an error model identifies at `error_values` (one list per model), if any.
    pub fn sensor_readings(&self, conditions: Conditions, error_values: &[Vec<f64>]) -> SensorReadings {
        let mut readings = conditions.sensors;
        for (m, v) in self.error_models.iter().zip(error_values) {
            if let Some((k, mounting)) = m.sensor_mounting(v)
                && let Some(r) = readings.get(k).copied()
            {
                readings.set(
                    k,
                    Some(GravityReading {
                        direction: mounting * r.direction,
                        ..r
                    }),
                );
            }
        }
        readings
    }

    /// The mounting of sensor `k` an error model identifies at `error_values` (one list per
    /// model): the rotation from the sensor's frame to its link's, if a model turns the chain
    /// by that sensor's reading ([`ErrorModel::sensor_mounting`](crate::ErrorModel::sensor_mounting)).
    pub fn sensor_mounting(&self, k: usize, error_values: &[Vec<f64>]) -> Option<nalgebra::UnitQuaternion<f64>> {
        (self.error_models.iter().zip(error_values))
            .find_map(|(m, v)| m.sensor_mounting(v).filter(|(s, _)| *s == k).map(|(_, r)| r))
    }

    /// The sensors read per measurement row, in the robot file's order (the slots of
    /// [`Conditions::sensors`]).
    pub fn sensors(&self) -> &[GravitySensor] {
        &self.sensors
    }

    /// The sensor whose reading gives the elastic models the direction of gravity: the one on
    /// the base, else the first declared; None without sensors.
    pub fn gravity_sensor(&self) -> Option<&GravitySensor> {
        self.gravity_sensor.map(|k| &self.sensors[k])
    }

    /// The mass model under `conditions` with the points of `tree`: the robot's own, or a copy
    /// in `scratch` when they carry a payload (that mass at the payload's site) or when `tree`
    /// moves the payload's point (calibration moving a marker the payload hangs at, or the
    /// convention frame the point is given in), so that a fit sees the payload where its
    /// model file will put it.
    pub fn mass_under<'a>(
        &'a self,
        conditions: Conditions,
        tree: &KinematicTree,
        scratch: &'a mut MassModel,
    ) -> &'a MassModel {
        if self.mass_is_own(conditions, tree) {
            return &self.mass;
        }
        scratch.clone_from(&self.mass);
        let (body, com) = self.payload_site(tree);
        let site = scratch.payload.get_or_insert(Payload { mass: 0.0, body, com });
        site.com = com;
        if let Some(m) = conditions.payload {
            site.mass = m;
        }
        scratch
    }

    /// Whether [`mass_under`](Robot::mass_under) is the robot's own mass model.
    fn mass_is_own(&self, conditions: Conditions, tree: &KinematicTree) -> bool {
        conditions.payload.is_none()
            && self
                .mass
                .payload
                .as_ref()
                .is_none_or(|p| p.com == self.payload_site(tree).1)
    }

    /// Body and position in it (m) where a payload hangs, with the points of `tree`.
    pub(super) fn payload_site(&self, tree: &KinematicTree) -> (usize, Vector3<f64>) {
        self.payload_point.map_or((0, Vector3::zeros()), |p| {
            let point = &tree.points()[p];
            (point.body, point.local.translation.vector)
        })
    }

    /// Adds the deformation of error model `model` alone, with parameter `values`, to `out`,
    /// at the rigid frames of the last [`forward_with_into`](Robot::forward_with_into) in `ws`
    /// (same `tree`, and the joint values and conditions of `sample`). Calibration
    /// differentiates models through this.
    pub fn model_perturbation_into(
        &self,
        model: usize,
        tree: &KinematicTree,
        values: &[f64],
        sample: &crate::data::measurement::Sample,
        ws: &RobotWorkspace,
        out: &mut Perturbation,
    ) {
        let conditions = Conditions::of(sample);
        let state = StaticState {
            q: &sample.q,
            tree,
            frames: &ws.rigid,
            mass: if ws.own_mass { &self.mass } else { &ws.mass },
            loads: &ws.loads,
            gravity: ws.gravity,
            temperature: conditions.temperature,
            sensors: ws.sensors,
        };
        self.error_models[model].perturb(&state, values, out);
    }

    /// Position of point `point` in the measurement frame for sample-like inputs, through the
    /// full model at the robot's own parameters (m).
    pub fn measured_position(
        &self,
        q: &[f64],
        point: usize,
        conditions: Conditions,
        ws: &mut RobotWorkspace,
    ) -> Vector3<f64> {
        self.forward_with_into(&self.tree, &self.error_values, q, conditions, ws);
        self.t_meas_base
            .transform_point(&ws.frames.point[point].translation.vector.into())
            .coords
    }

    /// Allocating convenience: checks `q`, evaluates the full model, returns the frames.
    pub fn forward(&self, q: &[f64]) -> Result<TreeWorkspace> {
        self.tree.check_q(q)?;
        let mut ws = self.workspace();
        self.forward_into(q, None, &mut ws);
        Ok(ws.frames)
    }
}
