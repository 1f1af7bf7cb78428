//! The import rule: within a crate, no two top-level modules import each other, directly or in a loop,
//! so that every crate reads bottom-up. A module is a file directly under `src/` (`host.rs`) or a folder
//! of them (`slots/`); it imports another when its code (comments and `#[cfg(test)]` modules aside)
//! names `crate::other` or, at the top level, `super::other`. Naming anything through the crate root
//! (`crate::RuntimeError` for an item `lib.rs` defines or re-exports) is an import of `lib.rs`, which
//! itself declares every module, so that is a loop too: modules name the module that defines an item.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

/// The crates held to the rule, by folder.
pub const CHECKED_CRATES: &[&str] = &["framework/runtime", "framework/ipc", "plugins/transport-loopback"];

/// The name `lib.rs` (or `main.rs`) goes by in the import graph.
const ROOT: &str = "<crate root>";

/// The import graph of one crate: for each top-level module, the modules its code names.
pub fn import_graph(crate_dir: &Path) -> Result<BTreeMap<String, BTreeSet<String>>> {
    let src = crate_dir.join("src");
    let mut modules: BTreeMap<String, Vec<PathBuf>> = BTreeMap::new();
    for entry in std::fs::read_dir(&src).with_context(|| format!("listing {}", src.display()))? {
        let path = entry?.path();
        let stem = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        if path.is_dir() {
            let mut files = Vec::new();
            rust_files(&path, &mut files)?;
            modules.entry(stem).or_default().extend(files);
        } else if path.extension().is_some_and(|e| e == "rs") {
            let name = if stem == "lib" || stem == "main" {
                ROOT.to_owned()
            } else {
                stem
            };
            modules.entry(name).or_default().push(path);
        }
    }
    let names: BTreeSet<String> = modules.keys().cloned().collect();
    let mut graph = BTreeMap::new();
    for (module, files) in &modules {
        let mut imports = BTreeSet::new();
        for file in files {
            let text =
                std::fs::read_to_string(file).with_context(|| format!("reading {}", file.display()))?;
            let top_level = file.parent() == Some(src.as_path());
            for named in named_modules(&text, top_level) {
                let target = if names.contains(&named) {
                    named
                } else {
                    ROOT.to_owned()
                };
                if &target != module {
                    imports.insert(target);
                }
            }
        }
        if module == ROOT {
            // The root declares every module.
            imports.extend(names.iter().filter(|name| *name != ROOT).cloned());
        }
        graph.insert(module.clone(), imports);
    }
    Ok(graph)
}

fn rust_files(dir: &Path, files: &mut Vec<PathBuf>) -> Result<()> {
    for entry in std::fs::read_dir(dir).with_context(|| format!("listing {}", dir.display()))? {
        let path = entry?.path();
        if path.is_dir() {
            rust_files(&path, files)?;
        } else if path.extension().is_some_and(|e| e == "rs") {
            files.push(path);
        }
    }
    Ok(())
}

/// The first path segment after every `crate::` (and, in a top-level file, `super::`) in code.
fn named_modules(text: &str, top_level: bool) -> BTreeSet<String> {
    let mut named = BTreeSet::new();
    let prefixes: &[&str] = if top_level {
        &["crate::", "super::"]
    } else {
        &["crate::"]
    };
    for line in text.lines() {
        if line.trim_start().starts_with("#[cfg(test)]") {
            break;
        }
        let code = line.split("//").next().unwrap_or("");
        for prefix in prefixes {
            let mut rest = code;
            while let Some(at) = rest.find(prefix) {
                let before = rest[..at].chars().next_back();
                rest = &rest[at + prefix.len()..];
                if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
                    continue;
                }
                let segment: String = rest
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if !segment.is_empty() {
                    named.insert(segment);
                } else if let Some(braced) = rest.strip_prefix('{') {
                    // `use crate::{a, b::c}`: every first segment in the braces.
                    let inner = braced.split('}').next().unwrap_or("");
                    for item in inner.split(',') {
                        let first: String = item
                            .trim()
                            .chars()
                            .take_while(|c| c.is_alphanumeric() || *c == '_')
                            .collect();
                        if !first.is_empty() {
                            named.insert(first);
                        }
                    }
                }
            }
        }
    }
    named
}

/// The loops of a graph: each set of two or more modules that reach one another (Tarjan's strongly
/// connected components), in name order.
pub fn loops(graph: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    let names: Vec<&String> = graph.keys().collect();
    let index_of: BTreeMap<&String, usize> = names.iter().enumerate().map(|(i, n)| (*n, i)).collect();
    let edges: Vec<Vec<usize>> = names
        .iter()
        .map(|name| {
            graph[*name]
                .iter()
                .filter_map(|target| index_of.get(target).copied())
                .collect()
        })
        .collect();
    let mut state = Tarjan {
        edges: &edges,
        index: vec![None; names.len()],
        low: vec![0; names.len()],
        on_stack: vec![false; names.len()],
        stack: Vec::new(),
        next: 0,
        components: Vec::new(),
    };
    for node in 0..names.len() {
        if state.index[node].is_none() {
            state.visit(node);
        }
    }
    let mut found: Vec<Vec<String>> = state
        .components
        .into_iter()
        .filter(|component| component.len() > 1)
        .map(|component| {
            let mut members: Vec<String> = component.into_iter().map(|i| names[i].clone()).collect();
            members.sort();
            members
        })
        .collect();
    found.sort();
    found
}

struct Tarjan<'a> {
    edges: &'a [Vec<usize>],
    index: Vec<Option<usize>>,
    low: Vec<usize>,
    on_stack: Vec<bool>,
    stack: Vec<usize>,
    next: usize,
    components: Vec<Vec<usize>>,
}

impl Tarjan<'_> {
    fn visit(&mut self, node: usize) {
        self.index[node] = Some(self.next);
        self.low[node] = self.next;
        self.next += 1;
        self.stack.push(node);
        self.on_stack[node] = true;
        for &target in &self.edges[node] {
            match self.index[target] {
                None => {
                    self.visit(target);
                    self.low[node] = self.low[node].min(self.low[target]);
                }
                Some(index) if self.on_stack[target] => self.low[node] = self.low[node].min(index),
                Some(_) => {}
            }
        }
        if Some(self.low[node]) == self.index[node] {
            let mut component = Vec::new();
            while let Some(member) = self.stack.pop() {
                self.on_stack[member] = false;
                component.push(member);
                if member == node {
                    break;
                }
            }
            self.components.push(component);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_read_from_code_only() {
        let text = "//! See [`crate::docs`].\nuse crate::{host::A, peers};\nuse super::x::Y; // crate::no\nfn f() { crate::stop::check(); my_crate::z(); }\n#[cfg(test)]\nmod t { use crate::later; }\n";
        let named: Vec<String> = named_modules(text, true).into_iter().collect();
        assert_eq!(named, ["host", "peers", "stop", "x"]);
    }

    #[test]
    fn loops_are_found_and_a_chain_is_not_one() {
        let graph = |edges: &[(&str, &str)]| {
            let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
            for (from, to) in edges {
                graph.entry((*from).into()).or_default().insert((*to).into());
                graph.entry((*to).into()).or_default();
            }
            graph
        };
        assert!(loops(&graph(&[("a", "b"), ("b", "c")])).is_empty());
        assert_eq!(
            loops(&graph(&[("a", "b"), ("b", "c"), ("c", "a"), ("c", "d")])),
            vec![vec!["a".to_owned(), "b".into(), "c".into()]]
        );
    }
}
