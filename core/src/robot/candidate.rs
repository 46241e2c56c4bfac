//! Diagnosis candidates: the instances of an error model the diagnosis workflow tries on a
//! robot. A plugin either instantiates itself (a function of the robot) or describes how with a
//! [`CandidateTemplate`] (run-time plugins, through the ABI): once per moving joint, once per
//! link or once for the whole arm, the joint or link name written into one field of its config.

use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

use crate::error::{Error, Result};
use crate::model::tree::Motion;
use crate::plugin::ErrorModelSpec;
use crate::robot::Robot;

/// One instance of an error model the diagnosis workflow may add to a robot.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// Where it acts: a joint or link name, or `global`.
    pub location: String,
    /// What a field engineer calls it, e.g. `joint j2 compliance`.
    pub label: String,
    /// The spec as the robot file's JSON form (with its `type`), at values that add nothing
    /// yet (zero compliances, unit rigidity scales): calibration identifies them.
    pub spec: Value,
}

/// How a plugin instantiates its candidates on a robot.
pub type CandidateFn = dyn Fn(&Robot) -> Vec<Candidate> + Send + Sync;

/// Where the instances of a templated candidate go.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CandidateScope {
    /// One per moving (revolute or prismatic) joint.
    Joint,
    /// One per link (every body but the base).
    Link,
    /// One for the whole robot.
    Global,
}

/// How to instantiate an error model that has no candidate function of its own, e.g.
/// `{"per": "link", "field": "link", "label": "cable sag", "config": {"mass_per_length": 0.0}}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CandidateTemplate {
    /// Once per joint, per link, or once.
    pub per: CandidateScope,
    /// The config field that receives the joint or link name (none for `global`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub field: Option<String>,
    /// What the effect is called, e.g. `cable sag`.
    pub label: String,
    /// The rest of the config, at values that add nothing until calibrated.
    #[serde(default)]
    pub config: Map<String, Value>,
}

impl CandidateTemplate {
    /// Reads a template from its JSON text and checks that it is complete.
    pub fn from_json(text: &str) -> Result<CandidateTemplate> {
        let invalid = |reason: String| Error::InvalidArgument {
            what: "candidate template".into(),
            reason,
        };
        let template: CandidateTemplate = serde_json::from_str(text).map_err(|e| invalid(e.to_string()))?;
        if template.label.trim().is_empty() {
            return Err(invalid("`label` is empty".into()));
        }
        match (template.per, &template.field) {
            (CandidateScope::Global, Some(f)) => Err(invalid(format!("a global candidate has no `field` (got `{f}`)"))),
            (CandidateScope::Joint | CandidateScope::Link, None) => Err(invalid(
                "a per-joint or per-link candidate needs the `field` that takes the name".into(),
            )),
            (_, Some(f)) if template.config.contains_key(f) => Err(invalid(format!(
                "`config` must not set `{f}`, which takes the joint or link name"
            ))),
            _ => Ok(template),
        }
    }

    /// The instances on `robot`. `spec` turns a config into the robot-file spec (with its
    /// `type`); instances the model rejects on this robot (a link without what it needs) are
    /// left out.
    pub fn instantiate(&self, robot: &Robot, spec: impl Fn(Value) -> Value) -> Vec<Candidate> {
        let tree = robot.tree();
        let sites: Vec<(String, String)> = match self.per {
            CandidateScope::Joint => tree
                .joints()
                .iter()
                .filter(|j| !matches!(j.motion, Motion::Fixed))
                .map(|j| (j.name.clone(), format!("joint {} {}", j.name, self.label)))
                .collect(),
            CandidateScope::Link => tree.bodies()[1..]
                .iter()
                .map(|b| (b.name.clone(), format!("{} link {}", b.name, self.label)))
                .collect(),
            CandidateScope::Global => vec![("global".into(), self.label.clone())],
        };
        sites
            .into_iter()
            .filter_map(|(location, label)| {
                let mut config = self.config.clone();
                if let Some(field) = &self.field {
                    config.insert(field.clone(), Value::String(location.clone()));
                }
                let spec = spec(Value::Object(config));
                builds_on(robot, &spec).then_some(Candidate { location, label, spec })
            })
            .collect()
    }
}

/// Whether `robot` with the error model `spec` added builds.
fn builds_on(robot: &Robot, spec: &Value) -> bool {
    let Ok(model) = serde_json::from_value::<Box<dyn ErrorModelSpec>>(spec.clone()) else {
        return false;
    };
    let mut file = robot.to_file();
    file.error_models.push(model);
    robot.rebuild(file).is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn templates_are_checked_for_what_instantiating_them_needs() {
        let ok = CandidateTemplate::from_json(
            r#"{"per": "link", "field": "link", "label": "cable sag", "config": {"mass_per_length": 0.0}}"#,
        )
        .unwrap();
        assert_eq!(ok.per, CandidateScope::Link);
        assert_eq!(ok.config["mass_per_length"], 0.0);
        for (text, what) in [
            (r#"{"per": "joint", "label": "x"}"#, "needs the `field`"),
            (r#"{"per": "global", "field": "link", "label": "x"}"#, "has no `field`"),
            (r#"{"per": "link", "field": "link", "label": " "}"#, "`label` is empty"),
            (
                r#"{"per": "link", "field": "link", "label": "x", "config": {"link": "boom"}}"#,
                "must not set `link`",
            ),
            (r#"{"per": "everywhere", "label": "x"}"#, "unknown variant"),
            (r#"{"per": "global", "label": "x", "extra": 1}"#, "unknown field"),
        ] {
            let e = CandidateTemplate::from_json(text).unwrap_err().to_string();
            assert!(e.contains(what), "{text}: {e}");
        }
    }
}
