//! The registry entry every plugin provides: its role, `type` name, schema and, for the
//! diagnosis, the candidates it offers.

use std::fmt::Debug;

use schemars::{Schema, SchemaGenerator};

use crate::robot::candidate::CandidateFn;
use crate::role::Role;

/// A registry entry: what `armcomp plugins` lists and `armcomp schema` composes.
#[derive(Clone, Copy)]
pub struct PluginInfo {
    /// The stable `type` name used in robot files.
    pub type_name: &'static str,
    /// Its role.
    pub role: Role,
    /// One line saying what it is.
    pub doc: &'static str,
    /// Whether the diagnosis workflow may try it as a missing effect.
    pub diagnosis_candidate: bool,
    /// The instances of the effect worth trying on a robot (per joint, per link or global),
    /// for the diagnosis workflow; `None` for plugins it cannot instantiate.
    pub candidates: Option<&'static CandidateFn>,
    /// Generates the JSON Schema of its spec (without the `type` field).
    pub schema: fn(&mut SchemaGenerator) -> Schema,
}

impl Debug for PluginInfo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PluginInfo")
            .field("type_name", &self.type_name)
            .field("role", &self.role)
            .finish()
    }
}
