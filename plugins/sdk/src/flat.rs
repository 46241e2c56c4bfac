//! The core's tree, mass model and static state as the flat arrays of [`crate::abi`], and back.
//!
//! The host flattens (safe code over owned buffers, reused between calls); the plugin side reads
//! the raw pointers back into core types, bit for bit, so a model sees exactly the numbers it
//! would see linked in.

use std::marker::PhantomData;

use armcomp_core::model::mass::{BeamRigidity, BodyMass, MassModel, Payload};
use armcomp_core::{Coordinate, Coupling, KinematicTree, Limits, Motion, StaticState, TreeWorkspace};
use nalgebra::{Isometry3, Quaternion, Translation3, Unit, UnitQuaternion, Vector3};

use crate::abi::*;

/// A string slice borrowed for the duration of a call.
pub fn abi_str(s: &str) -> AbiStr {
    AbiStr {
        ptr: s.as_ptr(),
        len: s.len(),
    }
}

/// Writes a pose as `[x, y, z, qi, qj, qk, qw]`.
#[inline]
pub fn write_pose(out: &mut [f64], x: &Isometry3<f64>) {
    let t = &x.translation.vector;
    let q = x.rotation.coords;
    out[..POSE_LEN].copy_from_slice(&[t.x, t.y, t.z, q[0], q[1], q[2], q[3]]);
}

/// Reads a pose written by [`write_pose`], keeping every bit (the quaternion is not renormalised).
#[inline]
pub fn read_pose(p: &[f64]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(p[0], p[1], p[2]),
        UnitQuaternion::new_unchecked(Quaternion::new(p[6], p[3], p[4], p[5])),
    )
}

fn poses<'a>(it: impl Iterator<Item = &'a Isometry3<f64>>) -> Vec<f64> {
    let mut out = Vec::new();
    for x in it {
        let at = out.len();
        out.resize(at + POSE_LEN, 0.0);
        write_pose(&mut out[at..], x);
    }
    out
}

/// The flat form of a tree, borrowing its names.
pub struct FlatTree<'a> {
    names: PhantomData<&'a KinematicTree>,
    n_joints: usize,
    n_points: usize,
    n_coordinates: usize,
    body_names: Vec<AbiStr>,
    body_convention_frames: Vec<f64>,
    joint_names: Vec<AbiStr>,
    joint_parents: Vec<usize>,
    joint_placements: Vec<f64>,
    joint_motions: Vec<u32>,
    joint_axes: Vec<f64>,
    joint_coordinates: Vec<u32>,
    coupling_starts: Vec<usize>,
    coupling_offsets: Vec<f64>,
    coupling_coordinates: Vec<usize>,
    coupling_multipliers: Vec<f64>,
    coordinate_limits: Vec<f64>,
    point_names: Vec<AbiStr>,
    point_bodies: Vec<usize>,
    point_locals: Vec<f64>,
}

impl<'a> FlatTree<'a> {
    /// Flattens `tree`.
    pub fn new(tree: &'a KinematicTree) -> Self {
        let joints = tree.joints();
        let mut flat = FlatTree {
            names: PhantomData,
            n_joints: joints.len(),
            n_points: tree.points().len(),
            n_coordinates: tree.nq(),
            body_names: tree.bodies().iter().map(|b| abi_str(&b.name)).collect(),
            body_convention_frames: poses(tree.bodies().iter().map(|b| &b.convention_frame)),
            joint_names: joints.iter().map(|j| abi_str(&j.name)).collect(),
            joint_parents: joints.iter().map(|j| j.parent).collect(),
            joint_placements: poses(joints.iter().map(|j| &j.placement)),
            joint_motions: Vec::new(),
            joint_axes: Vec::new(),
            joint_coordinates: Vec::new(),
            coupling_starts: vec![0],
            coupling_offsets: Vec::new(),
            coupling_coordinates: Vec::new(),
            coupling_multipliers: Vec::new(),
            coordinate_limits: tree
                .coordinate_limits()
                .iter()
                .flat_map(|l| match l {
                    Some(l) => [l.lower, l.upper],
                    None => [f64::NAN, f64::NAN],
                })
                .collect(),
            point_names: tree.points().iter().map(|p| abi_str(&p.name)).collect(),
            point_bodies: tree.points().iter().map(|p| p.body).collect(),
            point_locals: poses(tree.points().iter().map(|p| &p.local)),
        };
        for j in joints {
            let (code, axis) = match j.motion {
                Motion::Revolute(a) => (MOTION_REVOLUTE, a.into_inner()),
                Motion::Prismatic(a) => (MOTION_PRISMATIC, a.into_inner()),
                Motion::Fixed => (MOTION_FIXED, Vector3::zeros()),
            };
            flat.joint_motions.push(code);
            flat.joint_axes.extend_from_slice(axis.as_slice());
            let (code, offset) = match &j.coordinate {
                Coordinate::Independent(_) => (COORDINATE_INDEPENDENT, 0.0),
                Coordinate::Mimic(c) => {
                    for &(i, k) in &c.terms {
                        flat.coupling_coordinates.push(i);
                        flat.coupling_multipliers.push(k);
                    }
                    (COORDINATE_MIMIC, c.offset)
                }
                Coordinate::None => (COORDINATE_NONE, 0.0),
            };
            flat.joint_coordinates.push(code);
            flat.coupling_offsets.push(offset);
            flat.coupling_starts.push(flat.coupling_coordinates.len());
        }
        flat
    }

    /// The C view; valid while `self` lives.
    pub fn abi(&self) -> AbiTree {
        AbiTree {
            n_joints: self.n_joints,
            n_points: self.n_points,
            n_coordinates: self.n_coordinates,
            body_names: self.body_names.as_ptr(),
            body_convention_frames: self.body_convention_frames.as_ptr(),
            joint_names: self.joint_names.as_ptr(),
            joint_parents: self.joint_parents.as_ptr(),
            joint_placements: self.joint_placements.as_ptr(),
            joint_motions: self.joint_motions.as_ptr(),
            joint_axes: self.joint_axes.as_ptr(),
            joint_coordinates: self.joint_coordinates.as_ptr(),
            coupling_starts: self.coupling_starts.as_ptr(),
            coupling_offsets: self.coupling_offsets.as_ptr(),
            coupling_coordinates: self.coupling_coordinates.as_ptr(),
            coupling_multipliers: self.coupling_multipliers.as_ptr(),
            coordinate_limits: self.coordinate_limits.as_ptr(),
            point_names: self.point_names.as_ptr(),
            point_bodies: self.point_bodies.as_ptr(),
            point_locals: self.point_locals.as_ptr(),
        }
    }
}

/// The flat form of a mass model; refilled in place so that the perturb path does not allocate.
#[derive(Debug, Default)]
pub struct FlatMass {
    body_mass: Vec<f64>,
    body_com: Vec<f64>,
    body_beam: Vec<f64>,
    payload: Option<Payload>,
}

impl FlatMass {
    /// Copies `mass` in, reusing the buffers.
    pub fn fill(&mut self, mass: &MassModel) {
        self.body_mass.clear();
        self.body_com.clear();
        self.body_beam.clear();
        for b in &mass.bodies {
            self.body_mass.push(b.mass);
            self.body_com.extend_from_slice(b.com.as_slice());
            match &b.beam {
                Some(r) => self.body_beam.extend_from_slice(&[r.ei_y, r.ei_z, r.gj]),
                None => self.body_beam.extend_from_slice(&[f64::NAN; 3]),
            }
        }
        self.payload = mass.payload;
    }

    /// The C view; valid while `self` lives.
    pub fn abi(&self) -> AbiMass {
        let (payload_mass, payload_body, payload_com) = match &self.payload {
            Some(p) => (p.mass, p.body, [p.com.x, p.com.y, p.com.z]),
            None => (f64::NAN, 0, [0.0; 3]),
        };
        AbiMass {
            n_bodies: self.body_mass.len(),
            body_mass: self.body_mass.as_ptr(),
            body_com: self.body_com.as_ptr(),
            body_beam: self.body_beam.as_ptr(),
            payload_mass,
            payload_body,
            payload_com,
        }
    }
}

/// The flat form of a static state's frames and loads, refilled in place per call.
#[derive(Debug, Default)]
pub struct FlatState {
    body_frames: Vec<f64>,
    joint_frames: Vec<f64>,
    point_frames: Vec<f64>,
    mass: FlatMass,
}

fn fill_poses(out: &mut Vec<f64>, frames: &[Isometry3<f64>]) {
    out.resize(frames.len() * POSE_LEN, 0.0);
    for (chunk, x) in out.chunks_exact_mut(POSE_LEN).zip(frames) {
        write_pose(chunk, x);
    }
}

impl FlatState {
    /// Copies the frames and loads of `state` in, reusing the buffers, and returns the C view
    /// (valid while `self` and `state` live).
    pub fn fill(&mut self, state: &StaticState<'_>) -> AbiState {
        let f = state.frames;
        fill_poses(&mut self.body_frames, &f.body);
        fill_poses(&mut self.joint_frames, &f.joint_frame);
        fill_poses(&mut self.point_frames, &f.point);
        self.mass.fill(state.mass);
        AbiState {
            q: state.q.as_ptr(),
            n_q: state.q.len(),
            n_bodies: f.body.len(),
            n_joints: f.joint_frame.len(),
            n_points: f.point.len(),
            body_frames: self.body_frames.as_ptr(),
            joint_frames: self.joint_frames.as_ptr(),
            point_frames: self.point_frames.as_ptr(),
            joint_values: f.joint_value.as_ptr(),
            gravity: [state.gravity.x, state.gravity.y, state.gravity.z],
            temperature: state.temperature.unwrap_or(f64::NAN),
            mass: self.mass.abi(),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Plugin side: raw pointers back into core types.

/// A slice of `len` items at `ptr` (empty when `len` is 0, whatever `ptr` is).
///
/// # Safety
/// When `len > 0`, `ptr` must point to `len` initialised items that stay valid and unchanged
/// for `'a`.
pub(crate) unsafe fn slice<'a, T>(ptr: *const T, len: usize) -> Result<&'a [T], String> {
    if len == 0 {
        return Ok(&[]);
    }
    if ptr.is_null() {
        return Err(format!("null pointer for {len} values"));
    }
    // SAFETY: non-null, and the caller guarantees `len` valid items for `'a`.
    Ok(unsafe { std::slice::from_raw_parts(ptr, len) })
}

/// A mutable slice of `len` items at `ptr` (empty when `len` is 0, whatever `ptr` is).
///
/// # Safety
/// When `len > 0`, `ptr` must point to `len` initialised items that nothing else reads or
/// writes during `'a`.
pub(crate) unsafe fn slice_mut<'a, T>(ptr: *mut T, len: usize) -> Result<&'a mut [T], String> {
    if len == 0 {
        return Ok(&mut []);
    }
    if ptr.is_null() {
        return Err(format!("null pointer for {len} values"));
    }
    // SAFETY: non-null, and the caller guarantees `len` valid items, exclusively, for `'a`.
    Ok(unsafe { std::slice::from_raw_parts_mut(ptr, len) })
}

/// The text of an [`AbiStr`].
///
/// # Safety
/// As [`slice`], for `s.len` bytes at `s.ptr`.
pub(crate) unsafe fn text<'a>(s: AbiStr) -> Result<&'a str, String> {
    // SAFETY: forwarded from the caller.
    let bytes = unsafe { slice(s.ptr, s.len) }?;
    std::str::from_utf8(bytes).map_err(|e| format!("string is not UTF-8: {e}"))
}

/// Rebuilds the tree the host flattened, equal to the original.
///
/// # Safety
/// Every pointer of `t` must be valid for the lengths its counts declare (see [`AbiTree`]).
pub(crate) unsafe fn tree_from_abi(t: &AbiTree) -> Result<KinematicTree, String> {
    let (nj, nb, np, nc) = (t.n_joints, t.n_joints + 1, t.n_points, t.n_coordinates);
    // SAFETY: the caller guarantees each array's length as documented on AbiTree.
    let (body_names, frames, joint_names, parents, placements, motions, axes, coords, starts, offsets, limits) = unsafe {
        (
            slice(t.body_names, nb)?,
            slice(t.body_convention_frames, POSE_LEN * nb)?,
            slice(t.joint_names, nj)?,
            slice(t.joint_parents, nj)?,
            slice(t.joint_placements, POSE_LEN * nj)?,
            slice(t.joint_motions, nj)?,
            slice(t.joint_axes, 3 * nj)?,
            slice(t.joint_coordinates, nj)?,
            slice(t.coupling_starts, nj + 1)?,
            slice(t.coupling_offsets, nj)?,
            slice(t.coordinate_limits, 2 * nc)?,
        )
    };
    let n_terms = starts.last().copied().unwrap_or(0);
    // SAFETY: the coupling arrays hold `coupling_starts[n_joints]` terms.
    let (term_coords, term_mults) = unsafe {
        (
            slice(t.coupling_coordinates, n_terms)?,
            slice(t.coupling_multipliers, n_terms)?,
        )
    };
    // SAFETY: the point arrays hold `n_points` entries.
    let (point_names, point_bodies, point_locals) = unsafe {
        (
            slice(t.point_names, np)?,
            slice(t.point_bodies, np)?,
            slice(t.point_locals, POSE_LEN * np)?,
        )
    };
    // SAFETY: names point into the host's strings for the duration of the call.
    let name = |s: AbiStr| unsafe { text(s) };
    let mut tree = KinematicTree::new(name(body_names[0])?);
    let mut next_coordinate = 0;
    for j in 0..nj {
        let axis = Vector3::new(axes[3 * j], axes[3 * j + 1], axes[3 * j + 2]);
        // The host's axes are unit vectors already; renormalising could change their last bit.
        let motion = match motions[j] {
            MOTION_REVOLUTE => Motion::Revolute(Unit::new_unchecked(axis)),
            MOTION_PRISMATIC => Motion::Prismatic(Unit::new_unchecked(axis)),
            MOTION_FIXED => Motion::Fixed,
            other => return Err(format!("joint {j}: unknown motion code {other}")),
        };
        let placement = read_pose(&placements[POSE_LEN * j..]);
        let (jname, child) = (name(joint_names[j])?, name(body_names[j + 1])?);
        let added = match coords[j] {
            COORDINATE_MIMIC => {
                let range = starts[j]..starts[j + 1];
                let coupling = Coupling {
                    terms: term_coords[range.clone()]
                        .iter()
                        .copied()
                        .zip(term_mults[range].iter().copied())
                        .collect(),
                    offset: offsets[j],
                };
                tree.add_mimic_joint(jname, parents[j], placement, motion, coupling, child)
            }
            COORDINATE_INDEPENDENT | COORDINATE_NONE => {
                let limits = if coords[j] == COORDINATE_INDEPENDENT {
                    let (lo, hi) = (limits[2 * next_coordinate], limits[2 * next_coordinate + 1]);
                    next_coordinate += 1;
                    (!lo.is_nan()).then_some(Limits { lower: lo, upper: hi })
                } else {
                    None
                };
                tree.add_joint(jname, parents[j], placement, motion, limits, child)
            }
            other => return Err(format!("joint {j}: unknown coordinate code {other}")),
        };
        added.map_err(|e| e.to_string())?;
    }
    for b in 0..nb {
        tree.set_convention_frame(b, read_pose(&frames[POSE_LEN * b..]));
    }
    for p in 0..np {
        tree.add_point(
            name(point_names[p])?,
            point_bodies[p],
            read_pose(&point_locals[POSE_LEN * p..]),
        )
        .map_err(|e| e.to_string())?;
    }
    Ok(tree)
}

/// Copies a flat mass model into `out`, resizing it only when the body count changed.
///
/// # Safety
/// The pointers of `m` must be valid for `n_bodies` entries (see [`AbiMass`]).
pub(crate) unsafe fn mass_into(m: &AbiMass, out: &mut MassModel) -> Result<(), String> {
    let n = m.n_bodies;
    // SAFETY: the caller guarantees the documented lengths.
    let (mass, com, beam) = unsafe {
        (
            slice(m.body_mass, n)?,
            slice(m.body_com, 3 * n)?,
            slice(m.body_beam, 3 * n)?,
        )
    };
    out.bodies.resize(
        n,
        BodyMass {
            mass: 0.0,
            com: Vector3::zeros(),
            beam: None,
        },
    );
    for (k, b) in out.bodies.iter_mut().enumerate() {
        b.mass = mass[k];
        b.com = Vector3::new(com[3 * k], com[3 * k + 1], com[3 * k + 2]);
        b.beam = (!beam[3 * k].is_nan()).then(|| BeamRigidity {
            ei_y: beam[3 * k],
            ei_z: beam[3 * k + 1],
            gj: beam[3 * k + 2],
        });
    }
    out.payload = (!m.payload_mass.is_nan()).then(|| Payload {
        mass: m.payload_mass,
        body: m.payload_body,
        com: Vector3::from(m.payload_com),
    });
    Ok(())
}

/// Copies the rigid frames of a flat state into `out`, whose sizes must match the tree.
///
/// # Safety
/// The pointers of `s` must be valid for the counts it declares (see [`AbiState`]).
pub(crate) unsafe fn frames_into(s: &AbiState, out: &mut TreeWorkspace) -> Result<(), String> {
    if s.n_bodies != out.body.len() || s.n_joints != out.joint_frame.len() || s.n_points != out.point.len() {
        return Err(format!(
            "state of {} bodies, {} joints, {} points for a model built with {}, {}, {}",
            s.n_bodies,
            s.n_joints,
            s.n_points,
            out.body.len(),
            out.joint_frame.len(),
            out.point.len()
        ));
    }
    // SAFETY: the caller guarantees the documented lengths, just checked against the tree.
    let (bodies, joints, points, values) = unsafe {
        (
            slice(s.body_frames, POSE_LEN * s.n_bodies)?,
            slice(s.joint_frames, POSE_LEN * s.n_joints)?,
            slice(s.point_frames, POSE_LEN * s.n_points)?,
            slice(s.joint_values, s.n_joints)?,
        )
    };
    for (x, p) in out.body.iter_mut().zip(bodies.chunks_exact(POSE_LEN)) {
        *x = read_pose(p);
    }
    for (x, p) in out.joint_frame.iter_mut().zip(joints.chunks_exact(POSE_LEN)) {
        *x = read_pose(p);
    }
    for (x, p) in out.point.iter_mut().zip(points.chunks_exact(POSE_LEN)) {
        *x = read_pose(p);
    }
    out.joint_value.copy_from_slice(values);
    Ok(())
}
