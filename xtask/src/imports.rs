//! The import rule: no two modules of a crate import each other, directly or in a loop, at any depth, so
//! that every crate reads bottom-up. Each folder of modules (`src/` of the library, a module folder such
//! as `src/write/`, a binary's folder under `src/bin/`) has its own graph: its nodes are the files and
//! folders directly inside it and the folder's own root file (`lib.rs`, `main.rs` or `mod.rs`). A module
//! imports another when its code (comments and `#[cfg(test)]` modules aside) names a path into it through
//! `crate::`, `super::` or `self::`; the edge joins the two modules' branches where their paths part.
//! Declaring a module (`mod encode;`) is not an import, and neither is re-exporting its items
//! (`pub use encode::WrittenType;`, the folder's façade): naming a re-exported item imports the module it
//! comes from. Naming an item the root defines imports the root, so a root whose own code uses a module
//! that uses the root's items closes a loop. Modules declared under `#[cfg(test)]` are left out.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

/// The name a folder's root file goes by in its graph.
pub const ROOT: &str = "<root>";

/// A module's path from its crate root (`["write", "encode"]` for `src/write/encode.rs`).
type ModulePath = Vec<String>;

/// One folder's import graph: for each node, the nodes it imports.
pub type Graph = BTreeMap<String, BTreeSet<String>>;

/// Every import graph of the crate in `crate_dir`, by folder (its path from `src/`, `""` for `src/`).
pub fn import_graphs(crate_dir: &Path) -> Result<BTreeMap<String, Graph>> {
    let src = crate_dir.join("src");
    let mut graphs = BTreeMap::new();
    if !src.is_dir() {
        return Ok(graphs);
    }
    // The library (or the binary, when there is no library), then every binary under `src/bin/`.
    let mut trees = vec![(src.clone(), String::new())];
    let bin = src.join("bin");
    if bin.is_dir() {
        for entry in std::fs::read_dir(&bin).with_context(|| format!("listing {}", bin.display()))? {
            let path = entry?.path();
            if path.is_dir() {
                let name = path
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default();
                trees.push((path, format!("bin/{name}/")));
            }
        }
    }
    for (root_dir, label) in trees {
        let modules = module_files(&root_dir, root_dir == src)?;
        for (folder, graph) in tree_graphs(&modules)? {
            graphs.insert(format!("{label}{}", folder.join("/")), graph);
        }
    }
    Ok(graphs)
}

/// The files of one crate tree by module path. Under `src/` of a library, `main.rs` (a binary of its own
/// that names the library by its crate name) and `bin/` are other crates and left out.
fn module_files(root_dir: &Path, is_src: bool) -> Result<BTreeMap<ModulePath, Vec<PathBuf>>> {
    let mut modules: BTreeMap<ModulePath, Vec<PathBuf>> = BTreeMap::new();
    let has_lib = root_dir.join("lib.rs").is_file();
    let mut stack = vec![(root_dir.to_path_buf(), Vec::<String>::new())];
    while let Some((dir, path)) = stack.pop() {
        for entry in std::fs::read_dir(&dir).with_context(|| format!("listing {}", dir.display()))? {
            let file = entry?.path();
            let name = file
                .file_stem()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            if file.is_dir() {
                if !(is_src && path.is_empty() && name == "bin") {
                    let mut inner = path.clone();
                    inner.push(name);
                    stack.push((file, inner));
                }
                continue;
            }
            if file.extension().is_none_or(|ext| ext != "rs") {
                continue;
            }
            let at_top = path.is_empty();
            let module = match name.as_str() {
                "lib" if at_top => path.clone(),
                "main" if at_top && !(has_lib && is_src) => path.clone(),
                "main" if at_top => continue,
                "mod" => path.clone(),
                _ => {
                    let mut module = path.clone();
                    module.push(name);
                    module
                }
            };
            modules.entry(module).or_default().push(file);
        }
    }
    Ok(modules)
}

/// The graph of every folder of one tree.
fn tree_graphs(all_modules: &BTreeMap<ModulePath, Vec<PathBuf>>) -> Result<BTreeMap<ModulePath, Graph>> {
    let mut texts: BTreeMap<ModulePath, Vec<String>> = BTreeMap::new();
    for (module, files) in all_modules {
        for file in files {
            let text =
                std::fs::read_to_string(file).with_context(|| format!("reading {}", file.display()))?;
            texts.entry(module.clone()).or_default().push(text);
        }
    }
    // Test modules declared by a root, and everything inside them, are left out.
    let tests: BTreeSet<ModulePath> = texts
        .iter()
        .flat_map(|(module, texts)| {
            texts
                .iter()
                .flat_map(|text| test_modules(text))
                .map(move |name| [module.as_slice(), &[name]].concat())
        })
        .collect();
    let modules: BTreeMap<ModulePath, Vec<PathBuf>> = all_modules
        .iter()
        .filter(|(module, _)| !tests.iter().any(|test| module.starts_with(test)))
        .map(|(module, files)| (module.clone(), files.clone()))
        .collect();
    let modules = &modules;
    let reexports: BTreeMap<ModulePath, BTreeMap<String, ModulePath>> = texts
        .iter()
        .filter(|(module, _)| modules.contains_key(*module))
        .map(|(module, texts)| {
            let names = texts.iter().flat_map(|text| reexported(text, module)).collect();
            (module.clone(), names)
        })
        .collect();
    let mut graphs: BTreeMap<ModulePath, Graph> = BTreeMap::new();
    // Every module directly inside a folder is a node of its graph, and so is the folder's root.
    for module in modules.keys().filter(|m| !m.is_empty()) {
        let (folder, name) = module.split_at(module.len() - 1);
        let graph = graphs.entry(folder.to_vec()).or_default();
        graph.entry(name[0].clone()).or_default();
        graph.entry(ROOT.to_owned()).or_default();
    }
    for module in modules.keys() {
        for text in texts.get(module).into_iter().flatten() {
            for named in named_paths(&without_reexports(text), module) {
                let Some(target) = defining_module(modules, &reexports, &named) else {
                    continue;
                };
                let common = module.iter().zip(&target).take_while(|(a, b)| a == b).count();
                if common == target.len() && common == module.len() {
                    // A module naming its own items.
                    continue;
                }
                // A module's root naming a module inside it is the root's node in its own folder.
                let from = module.get(common).cloned().unwrap_or_else(|| ROOT.to_owned());
                let to = target.get(common).cloned().unwrap_or_else(|| ROOT.to_owned());
                let graph = graphs.entry(module[..common].to_vec()).or_default();
                graph.entry(to.clone()).or_default();
                graph.entry(from).or_default().insert(to);
            }
        }
    }
    Ok(graphs)
}

/// The module that defines what `path` names: its deepest module, or, when that module re-exports the
/// next segment, the module the re-export comes from (followed through chains of re-exports).
fn defining_module(
    modules: &BTreeMap<ModulePath, Vec<PathBuf>>,
    reexports: &BTreeMap<ModulePath, BTreeMap<String, ModulePath>>,
    path: &[String],
) -> Option<ModulePath> {
    let mut path = path.to_vec();
    for _ in 0..8 {
        let module = deepest_module(modules, &path)?;
        let Some(origin) = path
            .get(module.len())
            .and_then(|name| reexports.get(&module)?.get(name))
        else {
            return Some(module);
        };
        let mut next = origin.clone();
        next.extend_from_slice(&path[module.len() + 1..]);
        if next == path {
            return Some(module);
        }
        path = next;
    }
    deepest_module(modules, &path)
}

/// The names a file re-exports with `pub use` (or `pub(crate) use`), each with the absolute path it comes
/// from (the last segment being the item's own name).
fn reexported(text: &str, module: &[String]) -> Vec<(String, ModulePath)> {
    let mut found = Vec::new();
    let mut statement = String::new();
    for line in text.lines() {
        let code = line.split("//").next().unwrap_or("").trim();
        if line.trim_start().starts_with("#[cfg(test)]") {
            break;
        }
        if statement.is_empty() && !(code.starts_with("pub use ") || code.starts_with("pub(crate) use ")) {
            continue;
        }
        statement.push_str(code);
        statement.push(' ');
        if !code.ends_with(';') {
            continue;
        }
        let body = statement
            .trim()
            .trim_start_matches("pub(crate) use ")
            .trim_start_matches("pub use ")
            .trim_end_matches(';')
            .replace(' ', "");
        statement.clear();
        let relative =
            !(body.starts_with("crate::") || body.starts_with("self::") || body.starts_with("super::"));
        let body = if relative { format!("self::{body}") } else { body };
        let (base, tail) = resolve_prefix(&body, module);
        let (prefix, items) = match tail.find('{') {
            Some(at) => (&tail[..at], tail[at + 1..].trim_end_matches('}')),
            None => ("", tail),
        };
        let prefix: Vec<String> = prefix
            .split("::")
            .filter(|s| !s.is_empty())
            .map(str::to_owned)
            .collect();
        for item in items
            .split(',')
            .filter(|item| !item.is_empty() && !item.contains('{'))
        {
            let (item_path, alias) = match item.split_once("as") {
                Some((path, alias)) if !alias.is_empty() => (path, Some(alias)),
                _ => (item, None),
            };
            let segments: Vec<String> = item_path
                .split("::")
                .filter(|s| !s.is_empty())
                .map(str::to_owned)
                .collect();
            let Some(last) = segments.last() else { continue };
            if last == "*" || last == "self" {
                continue;
            }
            let name = alias.unwrap_or(last).to_owned();
            let mut origin = base.clone();
            origin.extend(prefix.iter().cloned());
            origin.extend(segments);
            found.push((name, origin));
        }
    }
    found
}

/// A file's text without its `pub use` statements: a re-export is the module's façade, not a use of
/// what it re-exports (those who name it through the façade import the module it comes from).
fn without_reexports(text: &str) -> String {
    let mut kept = String::new();
    let mut in_reexport = false;
    for line in text.lines() {
        let code = line.trim_start();
        if !in_reexport && (code.starts_with("pub use ") || code.starts_with("pub(crate) use ")) {
            in_reexport = true;
        }
        if in_reexport {
            in_reexport = !line.split("//").next().unwrap_or("").trim_end().ends_with(';');
            kept.push('\n');
            continue;
        }
        kept.push_str(line);
        kept.push('\n');
    }
    kept
}

/// The modules a file declares after `#[cfg(test)]` (`#[cfg(test)] mod tests;`).
fn test_modules(text: &str) -> Vec<String> {
    let mut found = Vec::new();
    let mut after_cfg_test = false;
    for line in text.lines() {
        let code = line.trim();
        if code.starts_with("#[cfg(test)]") {
            after_cfg_test = true;
            continue;
        }
        if after_cfg_test
            && let Some(name) = code
                .strip_prefix("mod ")
                .or_else(|| code.strip_prefix("pub mod "))
                .and_then(|rest| rest.strip_suffix(';'))
        {
            found.push(name.trim().to_owned());
        }
        if !code.starts_with("#[") {
            after_cfg_test = false;
        }
    }
    found
}

/// The longest prefix of `path` that is a module of the tree.
fn deepest_module(modules: &BTreeMap<ModulePath, Vec<PathBuf>>, path: &[String]) -> Option<ModulePath> {
    (0..=path.len())
        .rev()
        .map(|len| path[..len].to_vec())
        .find(|prefix| modules.contains_key(prefix))
}

/// Every path named in code through `crate::`, `super::` or `self::`, made absolute from the crate root
/// for a file of `module` (the module of `foo.rs` and of `foo/mod.rs` alike is `foo`: `super` is the
/// module above it).
fn named_paths(text: &str, module: &[String]) -> Vec<ModulePath> {
    let mut found = Vec::new();
    for line in text.lines() {
        if line.trim_start().starts_with("#[cfg(test)]") {
            break;
        }
        let code = line.split("//").next().unwrap_or("");
        let mut rest = code;
        while let Some((at, keyword)) = ["crate::", "super::", "self::"]
            .iter()
            .filter_map(|keyword| rest.find(keyword).map(|at| (at, *keyword)))
            .min()
        {
            let before = rest[..at].chars().next_back();
            let after = &rest[at..];
            rest = &rest[at + keyword.len()..];
            if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == '$' || c == ':') {
                continue;
            }
            let (base, tail) = resolve_prefix(after, module);
            for segments in segment_lists(tail) {
                let mut path = base.clone();
                path.extend(segments);
                found.push(path);
            }
            // Skip the prefix chain already read.
            rest = &after[after.len() - tail.len()..];
        }
    }
    found
}

/// The module a chain of `crate::`, `self::` and `super::` at the start of `text` leads to, and the text
/// after the chain.
fn resolve_prefix<'a>(mut text: &'a str, module: &[String]) -> (ModulePath, &'a str) {
    let mut base: ModulePath = module.to_vec();
    loop {
        if let Some(after) = text.strip_prefix("crate::") {
            base.clear();
            text = after;
        } else if let Some(after) = text.strip_prefix("self::") {
            text = after;
        } else if let Some(after) = text.strip_prefix("super::") {
            base.pop();
            text = after;
        } else {
            return (base, text);
        }
    }
}

/// The segment lists after a resolved prefix: `a::b::C` gives `[a, b, C]`; `{a::b, c}` gives `[a, b]`
/// and `[c]` (one level of braces).
fn segment_lists(text: &str) -> Vec<Vec<String>> {
    let path = |text: &str| -> Vec<String> {
        text.split("::")
            .map(|segment| {
                segment
                    .trim()
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect::<String>()
            })
            .take_while(|segment| !segment.is_empty())
            .collect()
    };
    if let Some(braced) = text.strip_prefix('{') {
        let inner = braced.split('}').next().unwrap_or("");
        inner.split(',').map(path).filter(|p| !p.is_empty()).collect()
    } else {
        let mut end = 0;
        for (index, c) in text.char_indices() {
            if c.is_alphanumeric() || c == '_' || c == ':' {
                end = index + c.len_utf8();
            } else {
                break;
            }
        }
        vec![path(&text[..end])]
    }
}

/// The loops of a graph: each set of two or more nodes that reach one another (Tarjan's strongly
/// connected components), in name order.
pub fn loops(graph: &Graph) -> Vec<Vec<String>> {
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

/// Every import loop of the crate in `crate_dir`, as `folder: a, b, …` lines.
pub fn crate_loops(crate_dir: &Path) -> Result<Vec<String>> {
    let mut found = Vec::new();
    for (folder, graph) in import_graphs(crate_dir)? {
        for members in loops(&graph) {
            let place = if folder.is_empty() {
                "src/".to_owned()
            } else {
                format!("src/{folder}/")
            };
            let edges: Vec<String> = members
                .iter()
                .flat_map(|from| {
                    graph[from]
                        .iter()
                        .filter(|to| members.contains(to))
                        .map(move |to| format!("{from} → {to}"))
                })
                .collect();
            found.push(format!("{place}: {} ({})", members.join(", "), edges.join(", ")));
        }
    }
    Ok(found)
}

/// Every crate of the workspace to hold to the rule: each folder under `root` with a `Cargo.toml` and a
/// `src/` (outside `target/`, `third_party/`, `fuzz/` and hidden folders).
pub fn workspace_crates(root: &Path) -> Result<Vec<PathBuf>> {
    let mut crates = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        if dir.join("Cargo.toml").is_file() && dir.join("src").is_dir() {
            crates.push(dir.clone());
        }
        for entry in std::fs::read_dir(&dir).with_context(|| format!("listing {}", dir.display()))? {
            let path = entry?.path();
            let name = path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            if path.is_dir()
                && !matches!(name.as_str(), "target" | "third_party" | "fuzz" | "src" | "tests")
                && !name.starts_with('.')
            {
                stack.push(path);
            }
        }
    }
    crates.sort();
    Ok(crates)
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

    fn module(path: &[&str]) -> ModulePath {
        path.iter().map(|s| (*s).to_owned()).collect()
    }

    #[test]
    fn paths_are_read_from_code_only_and_made_absolute() {
        let text = "//! See [`crate::docs`].\nuse crate::{host::A, peers};\nuse super::x::Y; // crate::no\n\
                    fn f() { crate::stop::check(); my_crate::z(); $crate::ffi::T; }\n#[cfg(test)]\nmod t { use crate::later; }\n";
        let named = named_paths(text, &module(&["write", "encode"]));
        let expected: Vec<ModulePath> = vec![
            module(&["host", "A"]),
            module(&["peers"]),
            module(&["write", "x", "Y"]),
            module(&["stop", "check"]),
        ];
        assert_eq!(named, expected);
        assert_eq!(
            named_paths("use self::a::B;\n", &module(&["w"])),
            vec![module(&["w", "a", "B"])]
        );
    }

    #[test]
    fn loops_are_found_and_a_chain_is_not_one() {
        let graph = |edges: &[(&str, &str)]| {
            let mut graph: Graph = BTreeMap::new();
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

    #[test]
    fn siblings_in_a_folder_and_a_root_that_uses_its_module_make_loops() {
        let dir = tempfile::tempdir().unwrap();
        let src = dir.path().join("src");
        std::fs::create_dir_all(src.join("write")).unwrap();
        std::fs::write(src.join("lib.rs"), "//! L.\npub mod write;\npub struct Top;\n").unwrap();
        std::fs::write(
            src.join("write/mod.rs"),
            "//! W.\nmod encode;\nmod viz;\npub use viz::Item;\n#[cfg(test)]\nmod tests;\n",
        )
        .unwrap();
        std::fs::write(src.join("write/encode.rs"), "//! E.\nuse super::viz::f;\n").unwrap();
        std::fs::write(src.join("write/viz.rs"), "//! V.\nuse super::encode::g;\n").unwrap();
        std::fs::write(src.join("write/tests.rs"), "//! T.\nuse super::*;\n").unwrap();
        let found = crate_loops(dir.path()).unwrap();
        assert_eq!(
            found,
            vec!["src/write/: encode, viz (encode → viz, viz → encode)".to_owned()]
        );
        // Naming a re-exported item imports the module it comes from, not the root that re-exports it.
        std::fs::write(src.join("write/viz.rs"), "//! V.\npub struct Item;\n").unwrap();
        std::fs::write(src.join("write/encode.rs"), "//! E.\nuse super::Item;\n").unwrap();
        assert!(crate_loops(dir.path()).unwrap().is_empty());
        // A root that uses a module which names an item the root defines closes a loop.
        std::fs::write(
            src.join("write/encode.rs"),
            "//! E.\nuse crate::Top;\npub fn g() {}\n",
        )
        .unwrap();
        std::fs::write(
            src.join("lib.rs"),
            "//! L.\npub mod write;\npub struct Top;\nfn f() { crate::write::g() }\n",
        )
        .unwrap();
        assert_eq!(
            crate_loops(dir.path()).unwrap(),
            vec!["src/: <root>, write (<root> → write, write → <root>)".to_owned()]
        );
    }
}
