//! The frames of a robot by name (its points, then its links) and Jacobians expressed in the
//! reference frames pinocchio users know.

use armcomp_core::{KinematicTree, TreeWorkspace};
use nalgebra::{Isometry3, Matrix6xX, Vector3};
use pyo3::prelude::*;

use crate::errors::input_error;

/// Every frame of a robot: its points (tool, markers, ...) in their order, then each link
/// (body) whose name no point has, at the link's origin.
#[derive(Debug, Clone)]
pub struct Frames {
    /// The names, in this order.
    pub names: Vec<String>,
    /// The robot's tree with a point at each of those links: frame `k` is its point `k`, so that
    /// a link's Jacobian is a point's.
    pub tree: KinematicTree,
}

impl Frames {
    /// The frames of `tree`.
    pub fn of(tree: &KinematicTree) -> Self {
        let mut extended = tree.clone();
        let mut names: Vec<String> = tree.points().iter().map(|p| p.name.clone()).collect();
        for (b, body) in tree.bodies().iter().enumerate() {
            if !names.contains(&body.name) {
                extended
                    .add_point(body.name.clone(), b, Isometry3::identity())
                    .expect("the body exists");
                names.push(body.name.clone());
            }
        }
        Frames { names, tree: extended }
    }

    /// The index of frame `name` (the tool for `None`).
    pub fn index(&self, name: Option<&str>, tool: usize) -> PyResult<usize> {
        match name {
            None => Ok(tool),
            Some(n) => self.names.iter().position(|f| f == n).ok_or_else(|| {
                input_error(
                    &format!(
                        "the robot has no frame `{n}`; its frames are its points and links: {}",
                        self.names.join(", ")
                    ),
                    None,
                    None,
                    Some("frame"),
                )
            }),
        }
    }

    /// The indices of `names` (every frame for `None`).
    pub fn indices(&self, names: Option<Vec<String>>, tool: usize) -> PyResult<Vec<usize>> {
        match names {
            None => Ok((0..self.names.len()).collect()),
            Some(list) => list.iter().map(|n| self.index(Some(n), tool)).collect(),
        }
    }
}

/// The frame a Jacobian's rows are expressed in, as pinocchio names them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reference {
    /// The frame's own axes: linear velocity of its origin and angular velocity, both in it.
    Local,
    /// The base frame at its origin: the velocity of the point of the moving frame that passes
    /// through the base's origin, and the angular velocity (a spatial velocity).
    World,
    /// The base's axes at the frame's origin: its origin's linear velocity and the angular
    /// velocity, in the base frame.
    LocalWorldAligned,
}

impl Reference {
    /// `"local"`, `"world"` or `"local_world_aligned"` (any case), or pinocchio's
    /// `ReferenceFrame` values, read by their `name`.
    pub fn parse(value: &Bound<'_, PyAny>) -> PyResult<Self> {
        let text: String = match value.extract() {
            Ok(t) => t,
            Err(_) => value.getattr("name").and_then(|n| n.extract()).map_err(|_| {
                input_error(
                    &format!("reference: expected \"local\", \"world\" or \"local_world_aligned\", got {value}"),
                    None,
                    None,
                    Some("reference"),
                )
            })?,
        };
        match text.to_ascii_lowercase().as_str() {
            "local" => Ok(Reference::Local),
            "world" => Ok(Reference::World),
            "local_world_aligned" => Ok(Reference::LocalWorldAligned),
            other => Err(input_error(
                &format!("unknown reference `{other}`; expected local, world or local_world_aligned"),
                None,
                None,
                Some("reference"),
            )),
        }
    }
}

/// The 6 × nq Jacobian of frame `k` of `frames` in `reference` into `out` (rows 0–2 linear,
/// 3–5 angular), of the rigid chain at the configuration `ws` holds the evaluation of
/// (`frames.tree.forward_into(q, ws)`, once for all frames of one configuration).
pub fn jacobian_into(frames: &Frames, k: usize, reference: Reference, ws: &TreeWorkspace, out: &mut Matrix6xX<f64>) {
    frames.tree.pose_jacobian_into(ws, k, out);
    let pose = ws.point[k];
    match reference {
        Reference::LocalWorldAligned => {}
        Reference::World => {
            let p = pose.translation.vector;
            for mut column in out.column_iter_mut() {
                let w = Vector3::new(column[3], column[4], column[5]);
                let v = Vector3::new(column[0], column[1], column[2]) - w.cross(&p);
                column.fixed_rows_mut::<3>(0).copy_from(&v);
            }
        }
        Reference::Local => {
            let r = pose.rotation.inverse();
            for mut column in out.column_iter_mut() {
                let v = r * Vector3::new(column[0], column[1], column[2]);
                let w = r * Vector3::new(column[3], column[4], column[5]);
                column.fixed_rows_mut::<3>(0).copy_from(&v);
                column.fixed_rows_mut::<3>(3).copy_from(&w);
            }
        }
    }
}
