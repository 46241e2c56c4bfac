//! The registry of built-in plugins and the robot-file schema composed from it.

use armcomp_core::{PluginInfo, RobotFile, Role};
use schemars::generate::SchemaSettings;
use serde_json::{Value, json};

/// Every plugin linked into this build, in a stable order (role, then registration order).
pub fn builtin_plugins() -> Vec<PluginInfo> {
    let mut all = armcomp_chains::plugins();
    all.extend(armcomp_elastic::plugins());
    all.extend(armcomp_urdf::plugins());
    all.extend(armcomp_sdk::plugins());
    all.extend(armcomp_learn::plugins());
    // Stable order by role so listings and the schema do not depend on registration order.
    all.sort_by_key(|p| match p.role {
        Role::Kinematics => 0,
        Role::ErrorModel => 1,
        Role::Predictor => 2,
    });
    all
}

/// The built-in plugins, then the types of every run-time plugin library loaded so far (robot
/// files name them with `type = "plugin"`, `model = "<type>"`).
pub fn plugins() -> Vec<PluginInfo> {
    let mut all = builtin_plugins();
    all.extend(armcomp_sdk::loaded_plugins());
    all
}

/// [`plugins`] as `armcomp plugins --json` lists them: each one's `type`, `role`, `doc` and
/// whether the diagnosis tries it (`diagnosis_candidate`).
pub fn plugins_json() -> serde_json::Value {
    plugins()
        .iter()
        .map(|p| {
            serde_json::json!({
                "type": p.type_name,
                "role": p.role,
                "doc": p.doc,
                "diagnosis_candidate": p.diagnosis_candidate,
            })
        })
        .collect()
}

/// Definition names of the placeholders in [`RobotFile`]'s schema, one per role.
fn placeholder(role: Role) -> &'static str {
    match role {
        Role::Kinematics => "KinematicsPlugin",
        Role::ErrorModel => "ErrorModelPlugin",
        Role::Predictor => "PredictorPlugin",
    }
}

/// The JSON Schema (draft 2020-12) of robot files: the file structure from core, with a `oneOf`
/// per plugin role listing each built-in plugin's own spec schema, tagged by its `type`. Run-time
/// plugins appear as the built-in `plugin` type; their configs are checked against their own
/// schemas when they are loaded.
pub fn robot_schema() -> Value {
    let mut generator = SchemaSettings::draft2020_12().into_generator();
    let plugins = builtin_plugins();
    let mut per_role: Vec<(Role, Vec<Value>)> = [Role::Kinematics, Role::ErrorModel, Role::Predictor]
        .into_iter()
        .map(|r| (r, Vec::new()))
        .collect();
    for p in &plugins {
        let mut schema = (p.schema)(&mut generator).to_value();
        let obj = schema
            .as_object_mut()
            .expect("plugin specs are structs, whose schemas are objects");
        obj.insert("title".into(), json!(p.type_name));
        obj.insert("description".into(), json!(p.doc));
        let props = obj.entry("properties").or_insert_with(|| json!({}));
        props["type"] = json!({ "const": p.type_name, "description": "Plugin type name." });
        let required = obj.entry("required").or_insert_with(|| json!([]));
        if let Some(list) = required.as_array_mut() {
            list.insert(0, json!("type"));
        }
        if let Some((_, list)) = per_role.iter_mut().find(|(r, _)| *r == p.role) {
            list.push(schema);
        }
    }
    let mut root = generator.into_root_schema_for::<RobotFile>().to_value();
    let defs = root["$defs"]
        .as_object_mut()
        .expect("the robot file schema has definitions");
    for (role, list) in per_role {
        // An empty oneOf is not valid JSON Schema; `false` rejects any entry of a role that has
        // no plugins in this build.
        let def = if list.is_empty() {
            json!(false)
        } else {
            json!({ "oneOf": list })
        };
        defs.insert(placeholder(role).into(), def);
    }
    root
}

/// [`robot_schema`] as the pretty-printed text committed at `schemas/robot.schema.json`.
pub fn schema_text() -> String {
    let mut text = serde_json::to_string_pretty(&robot_schema()).expect("a JSON value always serialises");
    text.push('\n');
    text
}
