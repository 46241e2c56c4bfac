//! The core library is layered: its folders, from the bottom up, are the [`LAYERS`], and a
//! module names only modules of its own layer or of the layers below it; among its modules no
//! chain of uses leads back to where it started. Read from the source: every `crate::<path>`
//! outside comments is a use (re-exports at the crate root are not used inside core, so each
//! use names its module).

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use crate::common::root;

/// Core's layers, bottom first: each entry is a folder of `core/src` (or a top-level file).
const LAYERS: [&[&str]; 10] = [
    &["error", "role"],
    &["support"],
    &["model"],
    &["kinematics"],
    &["data"],
    &["plugin"],
    &["robot"],
    &["algorithms"],
    &["calibrate"],
    &["analysis"],
];

fn layer_of(top: &str) -> Option<usize> {
    LAYERS.iter().position(|l| l.contains(&top))
}

/// Every Rust file under `dir`, recursively.
fn rust_files(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            files.extend(rust_files(&path));
        } else if path.extension().is_some_and(|e| e == "rs") {
            files.push(path);
        }
    }
    files.sort();
    files
}

/// The module a file is (`model::tree`; a folder's `mod.rs` is the folder), relative to `src`.
fn module_of(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let parts: Vec<_> = rel
        .iter()
        .map(|p| p.to_string_lossy().to_string())
        .filter(|p| p != "mod")
        .collect();
    parts.join("::")
}

/// The module a use names: the longest prefix of its path that is a module of `modules`.
fn named_module(path: &[String], modules: &BTreeSet<String>) -> Option<String> {
    (1..=path.len())
        .rev()
        .map(|n| path[..n].join("::"))
        .find(|m| modules.contains(m))
}

/// Module → the modules its code names, for every module of `src` but the crate root.
fn module_graph(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let files = rust_files(src);
    let modules: BTreeSet<String> = files.iter().map(|f| module_of(src, f)).collect();
    let mut graph = BTreeMap::new();
    for file in &files {
        let name = module_of(src, file);
        if name == "lib" {
            continue;
        }
        let mut deps = BTreeSet::new();
        for line in std::fs::read_to_string(file).unwrap().lines() {
            let code = line.split("//").next().unwrap();
            for (i, _) in code.match_indices("crate::") {
                let rest = &code[i + "crate::".len()..];
                assert!(
                    !rest.starts_with(|c: char| c.is_uppercase()) && !rest.starts_with('{'),
                    "{}: `{}` names a root re-export; name the module instead",
                    file.display(),
                    code.trim()
                );
                let path: Vec<String> = rest
                    .split("::")
                    .map(|s| {
                        s.chars()
                            .take_while(|c| c.is_alphanumeric() || *c == '_')
                            .collect::<String>()
                    })
                    .take_while(|s| s.starts_with(|c: char| c.is_lowercase()))
                    .collect();
                let used = named_module(&path, &modules)
                    .unwrap_or_else(|| panic!("{}: `{}` names no module of core", file.display(), code.trim()));
                if used != name {
                    deps.insert(used);
                }
            }
        }
        graph.insert(name, deps);
    }
    graph
}

/// Every cycle a depth-first walk meets, each as the modules along it.
fn cycles(graph: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    fn walk(
        u: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, u8>,
        stack: &mut Vec<String>,
        found: &mut Vec<Vec<String>>,
    ) {
        state.insert(u.to_string(), 1);
        stack.push(u.to_string());
        for v in graph.get(u).into_iter().flatten().filter(|v| graph.contains_key(*v)) {
            match state.get(v) {
                Some(1) => {
                    let at = stack.iter().position(|m| m == v).unwrap();
                    let mut cycle = stack[at..].to_vec();
                    cycle.push(v.clone());
                    found.push(cycle);
                }
                Some(_) => {}
                None => walk(v, graph, state, stack, found),
            }
        }
        stack.pop();
        state.insert(u.to_string(), 2);
    }
    let (mut state, mut stack, mut found) = (BTreeMap::new(), Vec::new(), Vec::new());
    for u in graph.keys() {
        if !state.contains_key(u) {
            walk(u, graph, &mut state, &mut stack, &mut found);
        }
    }
    found
}

#[test]
fn the_cycle_finder_finds_a_cycle_and_only_cycles() {
    let graph = |edges: &[(&str, &str)]| {
        let mut g: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for (a, b) in edges {
            g.entry(a.to_string()).or_default().insert(b.to_string());
            g.entry(b.to_string()).or_default();
        }
        g
    };
    assert!(cycles(&graph(&[("robot", "tree"), ("plugin", "tree"), ("robot", "plugin")])).is_empty());
    let found = cycles(&graph(&[
        ("robot", "collision"),
        ("collision", "tree"),
        ("tree", "robot"),
    ]));
    assert_eq!(found, [["collision", "tree", "robot", "collision"]]);
}

#[test]
fn core_modules_depend_one_way() {
    let graph = module_graph(&root().join("core/src"));
    assert!(graph.len() > 40 && graph["robot"].contains("model::tree"), "{graph:?}");
    let found = cycles(&graph);
    assert!(
        found.is_empty(),
        "core modules in a circle: {}",
        found.iter().map(|c| c.join(" → ")).collect::<Vec<_>>().join("; ")
    );
}

/// Each module uses its own layer and the layers below it, never one above: the folders are the
/// architecture a newcomer reads, so a use that climbs is an error here, not a surprise later.
#[test]
fn core_modules_use_only_their_layer_and_those_below() {
    let found = climbing(&module_graph(&root().join("core/src")));
    assert!(found.is_empty(), "uses that climb a layer: {}", found.join(", "));
}

/// Every use of a module in a higher layer, as `user → used`.
fn climbing(graph: &BTreeMap<String, BTreeSet<String>>) -> Vec<String> {
    let layer = |m: &str| {
        let top = m.split("::").next().unwrap();
        layer_of(top).unwrap_or_else(|| panic!("core/src/{top} is in no layer; add it to LAYERS"))
    };
    graph
        .iter()
        .flat_map(|(m, deps)| {
            deps.iter()
                .filter(|d| layer(d) > layer(m))
                .map(move |d| format!("{m} → {d}"))
        })
        .collect()
}

#[test]
fn the_layer_check_finds_a_use_that_climbs_and_only_those() {
    let graph = |edges: &[(&str, &str)]| {
        let mut g: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for (a, b) in edges {
            g.entry(a.to_string()).or_default().insert(b.to_string());
        }
        g
    };
    let fine = graph(&[
        ("robot", "model::tree"),
        ("analysis::diagnose", "calibrate"),
        ("model::tree", "error"),
    ]);
    assert!(climbing(&fine).is_empty());
    let found = climbing(&graph(&[
        ("robot", "model::tree"),
        ("model::tree", "robot"),
        ("data::split", "data::measurement"),
    ]));
    assert_eq!(found, ["model::tree → robot"]);
}

/// `core/src` shows its layers: its top level holds the crate root and a few files every layer
/// uses, and each folder is a layer.
#[test]
fn core_top_level_is_its_layers() {
    let src = root().join("core/src");
    let mut files = 0;
    for entry in std::fs::read_dir(&src).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        if path.is_dir() {
            assert!(layer_of(&name).is_some(), "core/src/{name}/ is in no layer");
        } else {
            files += 1;
            assert!(
                name == "lib" || layer_of(&name).is_some(),
                "core/src/{name}.rs is in no layer"
            );
        }
    }
    assert!(files <= 10, "{files} files at core/src's top level");
}

/// `unsafe` lives in the plugin SDK and the compensation library's C ABI alone, and the
/// compiler holds every other crate to it; those two document each block
/// (`clippy::undocumented_unsafe_blocks` denied there).
#[test]
fn unsafe_code_is_forbidden_outside_the_sdk_and_the_c_abi() {
    let roots = [
        "api/src/lib.rs",
        "core/src/lib.rs",
        "plugins/chains/src/lib.rs",
        "plugins/elastic/src/lib.rs",
        "plugins/learn/src/lib.rs",
        "plugins/urdf/src/lib.rs",
        "report/src/lib.rs",
        "repro/src/lib.rs",
        "python/src/lib.rs",
        "src/main.rs",
    ];
    for file in roots {
        let text = std::fs::read_to_string(root().join(file)).unwrap();
        assert!(
            text.lines().any(|l| l.trim() == "#![forbid(unsafe_code)]"),
            "{file} does not forbid unsafe code"
        );
    }
    for file in ["plugins/sdk/src/lib.rs", "ffi/src/lib.rs"] {
        let text = std::fs::read_to_string(root().join(file)).unwrap();
        assert!(text.contains("#![deny(clippy::undocumented_unsafe_blocks)]"), "{file}");
    }
}
