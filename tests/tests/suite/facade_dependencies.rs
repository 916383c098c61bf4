//! The `heml` library stays a library: nothing it pulls in may be a command-line,
//! progress-bar, plotting or thread-pinning crate (those belong to `heml-cli` and
//! `heml-validation`). Checked on `Cargo.lock`: the closure of `heml`'s dependencies
//! there is a superset of `cargo tree -p heml -e normal` (the lock file also lists
//! the dev-dependencies of workspace members), so a crate absent from it is absent
//! from the library's build. `.ci/run` also runs `cargo tree` itself.

use std::collections::{BTreeMap, BTreeSet};

/// `name -> dependency names` of every package in `Cargo.lock`.
fn lock_graph(text: &str) -> BTreeMap<String, Vec<String>> {
    let mut graph = BTreeMap::new();
    for block in text.split("[[package]]").skip(1) {
        let name = block
            .lines()
            .find_map(|l| l.strip_prefix("name = "))
            .map(|n| n.trim_matches('"').to_string())
            .expect("a [[package]] without a name");
        let deps = match block.find("dependencies = [") {
            Some(i) => block[i..]
                .lines()
                .skip(1)
                .take_while(|l| !l.starts_with(']'))
                // entries look like ` "name",` or ` "name 1.2.3",`
                .filter_map(|l| l.trim().trim_end_matches(',').trim_matches('"').split(' ').next())
                .map(str::to_string)
                .collect(),
            None => Vec::new(),
        };
        graph.entry(name).or_insert_with(Vec::new).extend(deps);
    }
    graph
}

fn closure(graph: &BTreeMap<String, Vec<String>>, root: &str) -> BTreeSet<String> {
    let mut seen = BTreeSet::new();
    let mut todo = vec![root.to_string()];
    while let Some(p) = todo.pop() {
        if seen.insert(p.clone()) {
            todo.extend(graph.get(&p).into_iter().flatten().cloned());
        }
    }
    seen
}

#[test]
fn the_library_pulls_in_no_application_crates() {
    let lock = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../Cargo.lock")).unwrap();
    let graph = lock_graph(&lock);
    // the check itself must see the crates it forbids, or it proves nothing
    for app in ["heml-cli", "heml-validation"] {
        let deps = closure(&graph, app);
        assert!(deps.contains("clap") || deps.contains("plotters"), "{app}: {deps:?}");
    }
    let lib = closure(&graph, "heml");
    assert!(lib.contains("heml-core") && lib.contains("nalgebra") && lib.contains("rayon"));
    for forbidden in [
        "plotters",
        "clap",
        "indicatif",
        "core_affinity",
        "criterion",
        "heml-validation",
    ] {
        assert!(!lib.contains(forbidden), "the heml library depends on {forbidden}");
    }
}
