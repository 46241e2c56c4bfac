//! The parameter space: every parameter calibration can touch, by name, and the robot with
//! a parameter vector written into its description.

use nalgebra::{Isometry3, UnitQuaternion, Vector3};

use super::SpaceParam;
use super::jacobian::frame_link_pose;
use super::{CalibrationParams, Decoded, ParamGroup, ParameterSpace, PriorGroup, fit_plane};
use crate::data::measurement::Sample;
use crate::error::{Error, Result};
use crate::model::geom::xyz_rpy;
use crate::model::param::{ParamInfo, Quantity};
use crate::model::tree::{KinematicTree, Motion};
use crate::robot::Robot;

impl ParameterSpace {
    /// The parameters of `robot`, starting at its current values.
    pub fn new(robot: &Robot) -> Self {
        let mut params = Vec::new();
        for (info, v) in robot.chain_params().iter().zip(robot.chain_values()) {
            let mut info = info.clone();
            info.nominal = *v;
            params.push(SpaceParam {
                info,
                group: ParamGroup::Geometry,
                model_type: String::new(),
            });
        }
        let n_chain = params.len();
        let mut error_offsets = Vec::new();
        let types = robot.error_model_types();
        for (i, ((m, values), model_type)) in robot
            .error_models()
            .iter()
            .zip(robot.error_values())
            .zip(types)
            .enumerate()
        {
            error_offsets.push(params.len());
            for (info, v) in m.params().iter().zip(values) {
                let mut info = info.clone();
                info.nominal = *v;
                params.push(SpaceParam {
                    info,
                    group: ParamGroup::ErrorModel(i),
                    model_type: model_type.clone(),
                });
            }
        }
        let base_offset = params.len();
        let mut setup = robot.setup_param_names().into_iter();
        let base_names: Vec<String> = setup.by_ref().take(crate::robot::BASE_NAMES.len()).collect();
        // One frame per station: `base.x` for one, `base[<station>].x` for several.
        let n_stations = robot.n_stations();
        for k in 0..n_stations {
            let (xyz, rpy) = base_xyz_rpy(&robot.station_frame(k));
            for (a, name) in crate::robot::BASE_NAMES.iter().enumerate() {
                let (quantity, value) = if a < 3 {
                    (Quantity::Length, xyz[a])
                } else {
                    (Quantity::Angle, rpy[a - 3])
                };
                let name = match robot.stations() {
                    [_, _, ..] => format!("base[{}].{name}", robot.stations()[k].name),
                    _ => base_names[a].clone(),
                };
                params.push(SpaceParam {
                    info: ParamInfo::new(name, quantity, value, f64::INFINITY),
                    group: ParamGroup::Base,
                    model_type: String::new(),
                });
            }
        }
        let marker_offset = params.len();
        let marker_dofs = robot.marker_dofs();
        for i in 0..robot.markers().len() {
            for a in 0..marker_dofs {
                params.push(SpaceParam {
                    info: ParamInfo::new(
                        setup.next().expect("a name per marker parameter"),
                        if a < 3 { Quantity::Length } else { Quantity::Angle },
                        0.0,
                        f64::INFINITY,
                    ),
                    group: ParamGroup::Marker(i),
                    model_type: String::new(),
                });
            }
        }
        ParameterSpace {
            fixed_point_offset: params.len(),
            fixed_points: Vec::new(),
            plane_offset: params.len(),
            planes: Vec::new(),
            plane_nominal: Vec::new(),
            params,
            n_chain,
            error_offsets,
            base_offset,
            n_stations,
            marker_offset,
            marker_dofs,
        }
    }

    /// The space with a position parameter triple (`fixed_point.<name>.x|y|z`, measurement
    /// frame, no prior) for every fixed point `samples` name, in order of first appearance.
    pub fn with_fixed_points(mut self, samples: &[Sample]) -> Self {
        for name in samples.iter().filter_map(|s| s.fixed_point.as_ref()) {
            if self.fixed_points.contains(name) {
                continue;
            }
            let i = self.fixed_points.len();
            for axis in ["x", "y", "z"] {
                self.params.push(SpaceParam {
                    info: ParamInfo::new(
                        format!("fixed_point.{name}.{axis}"),
                        Quantity::Length,
                        0.0,
                        f64::INFINITY,
                    ),
                    group: ParamGroup::FixedPoint(i),
                    model_type: String::new(),
                });
            }
            self.fixed_points.push(name.clone());
        }
        self.plane_offset = self.params.len();
        self
    }

    /// The space of `robot` with the nuisance parameters of `samples`: their fixed points
    /// ([`with_fixed_points`](Self::with_fixed_points)) and planes
    /// ([`with_planes`](Self::with_planes)).
    pub fn for_samples(robot: &Robot, samples: &[Sample]) -> Self {
        ParameterSpace::new(robot)
            .with_fixed_points(samples)
            .with_planes(robot, samples)
    }

    /// The space with three parameters (`plane.<name>.height`, `.roll`, `.pitch`: a shift
    /// along the normal, then turns about the plane's `x` and `y` axes; no prior) for every
    /// plane `samples` name, in order of first appearance, as offsets from the robot file's
    /// nominal pose of that plane or, when it has none, from the plane fitted in closed form to
    /// where the robot file's model puts the plane's contacts ([`fit_plane`]).
    pub fn with_planes(mut self, robot: &Robot, samples: &[Sample]) -> Self {
        let nominal = robot.nominal_planes();
        let contacts = (samples
            .iter()
            .any(|s| s.plane.as_ref().is_some_and(|p| !nominal.iter().any(|(n, _)| n == p))))
        .then(|| contact_poses(robot, samples));
        for name in samples.iter().filter_map(|s| s.plane.as_ref()) {
            if self.planes.contains(name) {
                continue;
            }
            let i = self.planes.len();
            for (c, quantity) in [
                ("height", Quantity::Length),
                ("roll", Quantity::Angle),
                ("pitch", Quantity::Angle),
            ] {
                self.params.push(SpaceParam {
                    info: ParamInfo::new(format!("plane.{name}.{c}"), quantity, 0.0, f64::INFINITY),
                    group: ParamGroup::Plane(i),
                    model_type: String::new(),
                });
            }
            self.planes.push(name.clone());
            let pose = match (nominal.iter().find(|(n, _)| n == name), &contacts) {
                (Some((_, t)), _) => *t,
                (None, Some(contacts)) => {
                    let rows = samples
                        .iter()
                        .zip(contacts)
                        .filter(|(s, _)| s.plane.as_ref() == Some(name));
                    let (points, axis) = rows.fold((Vec::new(), Vector3::zeros()), |(mut points, axis), (_, c)| {
                        points.push(c.translation.vector);
                        (points, axis + c.rotation * Vector3::z())
                    });
                    fit_plane(&points, &axis)
                }
                (None, None) => unreachable!("contacts are evaluated when a plane has no nominal"),
            };
            self.plane_nominal.push(pose);
        }
        self
    }

    /// Plane `i`'s pose (measurement frame) at `theta`: its nominal, shifted by `height` along
    /// its normal, then turned by `roll` and `pitch`.
    pub(super) fn plane_pose(&self, theta: &[f64], i: usize) -> Isometry3<f64> {
        let v = &theta[self.plane_offset + 3 * i..][..3];
        self.plane_nominal[i] * xyz_rpy([0.0, 0.0, v[0]], [v[1], v[2], 0.0])
    }

    /// Starting values of every parameter (SI; marker entries are offsets from the file's).
    pub fn initial(&self) -> Vec<f64> {
        self.params.iter().map(|p| p.info.nominal).collect()
    }

    /// Indices of the parameters named by `identify`: group words `base`, `markers`,
    /// `geometry` (of the measured chain: the joints that move a marker), `offsets` (its
    /// joint-value offsets: `θ` of revolute and `d` of prismatic joints, `offset` of URDF
    /// joints), `errors` (every error model), `all`, an error model's type name
    /// (e.g. `joint_compliance`), or a parameter name pattern with `*` wildcards (`j2.*`).
    /// Empty means `base, markers, geometry, errors`. What the robot file's `fixed` names is
    /// left out. The fixed points of fixed-point measurements and the planes of plane contacts
    /// are always selected, and the base frame never is then (they cannot see it).
    pub fn select(&self, robot: &Robot, identify: &[String]) -> Result<Vec<usize>> {
        let default = ["base", "markers", "geometry", "errors"].map(String::from);
        let words: &[String] = if identify.is_empty() { &default } else { identify };
        // Geometry words mean the chain the markers hang from: a joint elsewhere (another
        // limb, a wheel, a sensor mount) cannot move what was measured.
        let measured = robot.measured_joints();
        let on_measured_chain = |name: &str| {
            name.rsplit_once('.')
                .and_then(|(joint, _)| robot.tree().joint_index(joint))
                .is_none_or(|j| measured[j])
        };
        let mut chosen = vec![false; self.params.len()];
        for word in words {
            let word = word.trim();
            let mut any = false;
            for (k, p) in self.params.iter().enumerate() {
                let hit = match word {
                    "all" => true,
                    "base" => p.group == ParamGroup::Base,
                    "markers" => matches!(p.group, ParamGroup::Marker(_)),
                    "geometry" => p.group == ParamGroup::Geometry && on_measured_chain(&p.info.name),
                    "errors" => matches!(p.group, ParamGroup::ErrorModel(_)),
                    "fixed_points" => matches!(p.group, ParamGroup::FixedPoint(_)),
                    "planes" => matches!(p.group, ParamGroup::Plane(_)),
                    "offsets" => {
                        p.group == ParamGroup::Geometry
                            && on_measured_chain(&p.info.name)
                            && is_joint_offset(robot.tree(), &p.info.name)
                    }
                    w if w.contains('*') => crate::model::param::name_matches(w, &p.info.name),
                    w => p.model_type == w || p.info.name == w,
                };
                if hit {
                    chosen[k] = true;
                    any = true;
                }
            }
            if !any && !identify.is_empty() {
                let types = robot.error_model_types();
                let types = if types.is_empty() {
                    "it has none".to_string()
                } else {
                    types.join(", ")
                };
                return Err(Error::InvalidArgument {
                    what: "what to identify".into(),
                    reason: format!(
                        "`{word}` matches no parameter; use base, markers, geometry, offsets, errors, fixed_points, \
                         planes, all, an error model of this robot ({types}), or a name pattern such as `j2.*`"
                    ),
                });
            }
        }
        // What the robot file fixes is known: never refitted, whatever the words select.
        let fixed = robot.fixed();
        let no_instrument = robot.measures_without_instrument();
        Ok((0..self.params.len())
            .filter(|&k| match self.params[k].group {
                ParamGroup::FixedPoint(_) | ParamGroup::Plane(_) => true,
                ParamGroup::Base if no_instrument => false,
                _ => chosen[k],
            })
            .filter(|&k| {
                !fixed
                    .iter()
                    .any(|f| crate::model::param::name_matches(f, &self.params[k].info.name))
            })
            .collect())
    }

    /// Decodes a full parameter vector into what forward kinematics needs.
    pub(super) fn decode(&self, robot: &Robot, theta: &[f64]) -> Result<Decoded> {
        let errors = self
            .error_offsets
            .iter()
            .zip(robot.error_values())
            .map(|(&o, v)| theta[o..o + v.len()].to_vec())
            .collect();
        Ok(Decoded {
            tree: self.tree(robot, theta)?,
            errors,
            frames: (0..self.n_stations).map(|k| self.base_pose(theta, k)).collect(),
            fixed_points: (0..self.fixed_points.len())
                .map(|i| Vector3::from_column_slice(&theta[self.fixed_point_offset + 3 * i..][..3]))
                .collect(),
            planes: (0..self.planes.len()).map(|i| self.plane_pose(theta, i)).collect(),
        })
    }

    /// The tree of the chain parameters of `theta` with the markers moved by their offsets:
    /// error models see the points where the model file will put them (a payload hanging at a
    /// marker, a point on a bending link).
    pub(super) fn tree(&self, robot: &Robot, theta: &[f64]) -> Result<KinematicTree> {
        let mut tree = robot.tree_for(&theta[..self.n_chain])?;
        for (i, &m) in robot.markers().iter().enumerate() {
            let o = self.marker_offset + self.marker_dofs * i;
            let delta = Vector3::new(theta[o], theta[o + 1], theta[o + 2]);
            let turn = self.marker_turn(theta, i);
            if delta != Vector3::zeros() || turn != Vector3::zeros() {
                let point = &tree.points()[m];
                let mut local = point.local;
                // Offsets are in the body's convention frame, as the file's coordinates.
                local.translation.vector += tree.bodies()[point.body].convention_frame.rotation * delta;
                // Turns are about the point's own axes, which the file's rpy then absorbs.
                local.rotation *= UnitQuaternion::from_scaled_axis(turn);
                tree.set_point_local(m, local);
            }
        }
        Ok(tree)
    }

    /// Marker `i`'s orientation offset in `theta` (rotation vector, rad; zero when the robot
    /// measures positions only).
    pub(super) fn marker_turn(&self, theta: &[f64], i: usize) -> Vector3<f64> {
        if self.marker_dofs < 6 {
            return Vector3::zeros();
        }
        let o = self.marker_offset + self.marker_dofs * i + 3;
        Vector3::new(theta[o], theta[o + 1], theta[o + 2])
    }

    /// Station `k`'s measurement frame in `theta`.
    pub(super) fn base_pose(&self, theta: &[f64], k: usize) -> Isometry3<f64> {
        let b = &theta[self.station_params(k)];
        xyz_rpy([b[0], b[1], b[2]], [b[3], b[4], b[5]])
    }

    /// The indices of station `k`'s six frame parameters.
    pub(super) fn station_params(&self, k: usize) -> std::ops::Range<usize> {
        self.base_offset + 6 * k..self.base_offset + 6 * (k + 1)
    }

    /// The station whose frame parameter `k` is.
    pub(super) fn station_of(&self, k: usize) -> usize {
        (k - self.base_offset) / 6
    }
}

/// The pose of every sample's measured point in its measurement frame as the robot file's
/// model puts it.
fn contact_poses(robot: &Robot, samples: &[Sample]) -> Vec<Isometry3<f64>> {
    let mut ws = robot.workspace();
    samples
        .iter()
        .map(|s| {
            robot.forward_with_into(
                robot.tree(),
                robot.error_values(),
                &s.q,
                crate::robot::Conditions::of(s),
                &mut ws,
            );
            let link = frame_link_pose(robot, robot.tree(), &ws);
            robot.station_frame(s.station) * link.inverse() * ws.frames.point[s.point]
        })
        .collect()
}

/// Whether chain parameter `name` (`<joint>.<suffix>`) adds to its joint's value.
pub(super) fn is_joint_offset(tree: &KinematicTree, name: &str) -> bool {
    let Some((joint, suffix)) = name.rsplit_once('.') else {
        return false;
    };
    match tree.joint_index(joint).map(|j| &tree.joints()[j].motion) {
        Some(Motion::Revolute(_)) => suffix == "theta" || suffix == "offset",
        Some(Motion::Prismatic(_)) => suffix == "d" || suffix == "offset",
        _ => false,
    }
}

pub(super) fn base_xyz_rpy(t: &Isometry3<f64>) -> ([f64; 3], [f64; 3]) {
    let (r, p, y) = t.rotation.euler_angles();
    let v = t.translation.vector;
    ([v.x, v.y, v.z], [r, p, y])
}

/// The robot's parameter space with the fixed points of `samples` and the priors `params`
/// asks for (scaled by its `prior_scale`, or none).
pub(super) fn prior_space(robot: &Robot, params: &CalibrationParams, samples: &[Sample]) -> ParameterSpace {
    let mut space = ParameterSpace::for_samples(robot, samples);
    for k in 0..space.params.len() {
        let group = space.prior_group(robot, k);
        let group_scale: f64 = params
            .group_prior_scales
            .iter()
            .filter(|(g, _)| *g == group || *g == PriorGroup::Parameter(k))
            .map(|(_, s)| s)
            .product();
        let info = &mut space.params[k].info;
        info.sigma = if params.use_priors {
            info.sigma * params.prior_scale * group_scale
        } else {
            f64::INFINITY
        };
    }
    space
}

impl ParameterSpace {
    /// The prior group of parameter `k` (see [`PriorGroup`]).
    pub fn prior_group(&self, robot: &Robot, k: usize) -> PriorGroup {
        let p = &self.params[k];
        match p.group {
            ParamGroup::Base => PriorGroup::Frame,
            ParamGroup::Marker(_) => PriorGroup::Markers,
            ParamGroup::FixedPoint(_) => PriorGroup::FixedPoints,
            ParamGroup::Plane(_) => PriorGroup::Planes,
            ParamGroup::ErrorModel(i) => PriorGroup::ErrorModel(i),
            ParamGroup::Geometry if is_joint_offset(robot.tree(), &p.info.name) => PriorGroup::JointOffsets,
            ParamGroup::Geometry if p.info.quantity == Quantity::Angle => PriorGroup::Angles,
            ParamGroup::Geometry => PriorGroup::Lengths,
        }
    }
}

impl ParameterSpace {
    /// The robot with every parameter of `theta` (a full vector, as [`initial`](Self::initial))
    /// written into its description.
    pub fn apply(&self, robot: &Robot, theta: &[f64]) -> Result<Robot> {
        apply(robot, self, theta)
    }

    /// Index of the parameter called `name`.
    pub fn index(&self, name: &str) -> Option<usize> {
        self.params.iter().position(|p| p.info.name == name)
    }
}

pub(super) fn apply(robot: &Robot, space: &ParameterSpace, theta: &[f64]) -> Result<Robot> {
    if theta.len() != space.params.len() {
        return Err(Error::Dimension {
            what: "calibration parameters".into(),
            expected: space.params.len(),
            got: theta.len(),
        });
    }
    let errors: Vec<Vec<f64>> = space
        .error_offsets
        .iter()
        .zip(robot.error_values())
        .map(|(&o, v)| theta[o..o + v.len()].to_vec())
        .collect();
    let mut file = robot.file_with(&theta[..space.n_chain], &errors);
    let units = file.units;
    let b = &theta[space.station_params(0)];
    let measurement = file.measurement.get_or_insert_with(Default::default);
    measurement.base_xyz = [b[0], b[1], b[2]].map(|v| units.len_out(v));
    measurement.base_rpy = [b[3], b[4], b[5]].map(|v| units.ang_out(v));
    for (k, station) in measurement.stations.iter_mut().enumerate() {
        let b = &theta[space.station_params(k)];
        station.base_xyz = [b[0], b[1], b[2]].map(|v| units.len_out(v));
        station.base_rpy = [b[3], b[4], b[5]].map(|v| units.ang_out(v));
    }
    for (i, &m) in robot.markers().iter().enumerate() {
        let name = &robot.tree().points()[m].name;
        let o = space.marker_offset + space.marker_dofs * i;
        let turn = space.marker_turn(theta, i);
        if let Some(p) = file.points.iter_mut().find(|p| &p.name == name) {
            for a in 0..3 {
                p.xyz[a] += units.len_out(theta[o + a]);
            }
            if turn != Vector3::zeros() {
                let rpy = units.ang3(p.rpy);
                let r = xyz_rpy([0.0; 3], rpy).rotation * UnitQuaternion::from_scaled_axis(turn);
                let (roll, pitch, yaw) = r.euler_angles();
                p.rpy = [roll, pitch, yaw].map(|v| units.ang_out(v));
            }
        }
    }
    // The identified planes become the model's nominal ones, so that `evaluate` scores rows
    // of the same planes against them.
    for i in 0..space.planes.len() {
        let (xyz, rpy) = base_xyz_rpy(&space.plane_pose(theta, i));
        let spec = crate::robot::robot_file::PlaneSpec {
            name: space.planes[i].clone(),
            xyz: xyz.map(|v| units.len_out(v)),
            rpy: rpy.map(|v| units.ang_out(v)),
        };
        match measurement.planes.iter_mut().find(|p| p.name == spec.name) {
            Some(p) => *p = spec,
            None => measurement.planes.push(spec),
        }
    }
    robot.rebuild(file)
}
