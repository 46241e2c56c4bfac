//! The core library's modules depend on each other one way: no module reaches, through the
//! modules it uses, back to itself. Read from the source: every `crate::<module>` outside
//! comments is a dependency (re-exports at the crate root are not used inside core, so each
//! dependency names its module).

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use crate::common::root;

/// Module → the modules its code names, for the top-level modules of `src` (a folder module
/// counts as one).
fn module_graph(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let mut graph = BTreeMap::new();
    for entry in std::fs::read_dir(src).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        if name == "lib" {
            continue;
        }
        let files: Vec<_> = if path.is_dir() {
            std::fs::read_dir(&path).unwrap().map(|e| e.unwrap().path()).collect()
        } else {
            vec![path.clone()]
        };
        let mut deps = BTreeSet::new();
        for file in files {
            for line in std::fs::read_to_string(&file).unwrap().lines() {
                let code = line.split("//").next().unwrap();
                for (i, _) in code.match_indices("crate::") {
                    let rest = &code[i + "crate::".len()..];
                    let word: String = rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
                    assert!(
                        !word.starts_with(|c: char| c.is_uppercase()) && !rest.starts_with('{'),
                        "{}: `{}` names a root re-export; name the module instead",
                        file.display(),
                        code.trim()
                    );
                    if word != name {
                        deps.insert(word);
                    }
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
    assert!(graph.len() > 20 && graph["robot"].contains("tree"), "{graph:?}");
    let found = cycles(&graph);
    assert!(
        found.is_empty(),
        "core modules in a circle: {}",
        found.iter().map(|c| c.join(" → ")).collect::<Vec<_>>().join("; ")
    );
}

/// `unsafe` lives in the plugin SDK alone, and the compiler holds every other crate to it; the
/// SDK documents each block (`clippy::undocumented_unsafe_blocks` denied there).
#[test]
fn unsafe_code_is_forbidden_outside_the_sdk() {
    let roots = [
        "core/src/lib.rs",
        "plugins/chains/src/lib.rs",
        "plugins/elastic/src/lib.rs",
        "plugins/learn/src/lib.rs",
        "plugins/urdf/src/lib.rs",
        "report/src/lib.rs",
        "repro/src/lib.rs",
        "python/src/lib.rs",
        "src/lib.rs",
        "src/main.rs",
    ];
    for file in roots {
        let text = std::fs::read_to_string(root().join(file)).unwrap();
        assert!(
            text.lines().any(|l| l.trim() == "#![forbid(unsafe_code)]"),
            "{file} does not forbid unsafe code"
        );
    }
    let sdk = std::fs::read_to_string(root().join("plugins/sdk/src/lib.rs")).unwrap();
    assert!(sdk.contains("#![deny(clippy::undocumented_unsafe_blocks)]"));
}
