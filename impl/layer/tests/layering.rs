//! The library stands apart from the tools, and its modules import in one direction.
//!
//! Cargo already refuses a dependency cycle between packages, so what can go wrong is a
//! dependency the library should not have (a tool crate, through a path) and a cycle among a
//! crate's own top-level modules (`runtime` using `api` while `api` uses `runtime`), which
//! the compiler accepts. Both are read from the sources: every path that starts at `crate`
//! or climbs with `super` is resolved to the top-level module it lands in, doc comments
//! aside (they are attributes, not paths; a path inside a macro's arguments is not read
//! either, which only ever hides an edge that a `use` elsewhere shows). The tools' crate (`impl/src`) is held to the same
//! rule, so a layer below never reaches up.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use syn::visit::Visit;

/// Top-level module -> the top-level modules its code names.
type Graph = BTreeMap<String, BTreeSet<String>>;

const LAYER: &str = env!("CARGO_MANIFEST_DIR");

#[test]
fn the_library_depends_on_no_tool() {
    let manifest = read(&Path::new(LAYER).join("Cargo.toml"));
    let manifest: toml::Table = manifest.parse().expect("layer/Cargo.toml is TOML");
    for table in ["dependencies", "dev-dependencies", "build-dependencies"] {
        let Some(deps) = manifest.get(table).and_then(|d| d.as_table()) else {
            continue;
        };
        for (name, spec) in deps {
            let path = spec.get("path").and_then(|p| p.as_str());
            // The core is the one crate of ours below the layer.
            assert!(
                path.is_none() || path == Some("../core"),
                "[{table}] {name} = {spec}: the library may depend on the core only, not on a tool crate"
            );
        }
    }
}

#[test]
fn the_librarys_modules_import_in_one_direction() {
    let graph = module_graph(&Path::new(LAYER).join("src"));
    assert!(graph.len() > 10, "read {} modules", graph.len());
    assert_eq!(cycle(&graph), None, "a cycle among the library's modules");
}

#[test]
fn the_tools_modules_import_in_one_direction() {
    let graph = module_graph(&Path::new(LAYER).join("../src"));
    assert!(
        graph.contains_key("controller"),
        "read the tools: {graph:?}"
    );
    assert_eq!(cycle(&graph), None, "a cycle among the tools' modules");
}

/// The check itself can fail: the cycle the library once had (api and runtime importing each
/// other) is found, with its path, in a graph that has it.
#[test]
fn a_cycle_is_found_and_named() {
    let mut graph = module_graph(&Path::new(LAYER).join("src"));
    assert!(graph["api"].contains("runtime"));
    graph.get_mut("runtime").unwrap().insert("api".into());
    let found = cycle(&graph).expect("the added import closes a cycle");
    assert_eq!(found.first(), found.last());
    assert!(found.contains(&"api".to_string()) && found.contains(&"runtime".to_string()));
}

/// And the reader sees imports written in every form: grouped, nested, in expressions,
/// through `super`, and the crate root's re-exports; it does not count doc comments.
#[test]
fn every_form_of_an_import_is_read() {
    let source = r#"
        //! See [`crate::demo`].
        use crate::{config::Config, dds::{self, Session}};
        mod inner { fn f() { super::super::super::wire::decode(); super::output::g(); } }
        fn g() -> crate::Error { crate::leds::off(); todo!() }
    "#;
    let roots = BTreeMap::from([("Error".to_string(), "error".to_string())]);
    let named = imports_of(source, &["runtime".into(), "arrival".into()], &roots);
    // `super::output` from runtime::arrival::inner is runtime's own output module.
    let expected: BTreeSet<String> = ["config", "dds", "wire", "error", "leds", "runtime"]
        .map(String::from)
        .into();
    assert_eq!(named, expected);
}

/// A cycle in `graph`, as the path that closes it (first == last), if there is one.
fn cycle(graph: &Graph) -> Option<Vec<String>> {
    fn visit(
        node: &str,
        graph: &Graph,
        done: &mut BTreeSet<String>,
        path: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        if let Some(at) = path.iter().position(|n| n == node) {
            let mut found = path[at..].to_vec();
            found.push(node.to_string());
            return Some(found);
        }
        if done.contains(node) {
            return None;
        }
        path.push(node.to_string());
        for next in graph.get(node).into_iter().flatten() {
            if let Some(found) = visit(next, graph, done, path) {
                return Some(found);
            }
        }
        path.pop();
        done.insert(node.to_string());
        None
    }
    let mut done = BTreeSet::new();
    graph
        .keys()
        .find_map(|node| visit(node, graph, &mut done, &mut Vec::new()))
}

/// Every top-level module under `src` and the top-level modules it names.
fn module_graph(src: &Path) -> Graph {
    let roots = root_reexports(&read(&src.join("lib.rs")));
    let mut graph = Graph::new();
    for file in rust_files(src) {
        let relative = file.strip_prefix(src).expect("under src");
        let module = module_path(relative);
        let Some(top) = module.first().cloned() else {
            continue; // lib.rs and main.rs: the roots, not modules
        };
        let named = imports_of(&read(&file), &module, &roots);
        let entry = graph.entry(top.clone()).or_default();
        entry.extend(named.into_iter().filter(|m| *m != top));
    }
    // Only edges between modules of this crate (`core` is the core crate, re-exported).
    let modules: BTreeSet<String> = graph.keys().cloned().collect();
    for named in graph.values_mut() {
        named.retain(|m| modules.contains(m));
    }
    graph
}

/// `pub use error::Error;` at the crate root: `crate::Error` is the `error` module's.
fn root_reexports(lib_rs: &str) -> BTreeMap<String, String> {
    let file = syn::parse_file(lib_rs).expect("lib.rs parses");
    let mut roots = BTreeMap::new();
    for item in file.items {
        if let syn::Item::Use(item) = item {
            if let syn::UseTree::Path(path) = &item.tree {
                if let syn::UseTree::Name(name) = &*path.tree {
                    roots.insert(name.ident.to_string(), path.ident.to_string());
                }
            }
        }
    }
    roots
}

/// The module path of a file under `src`: `runtime/arrival/tests.rs` -> runtime, arrival,
/// tests; `dds/mod.rs` -> dds; `lib.rs` -> nothing.
fn module_path(relative: &Path) -> Vec<String> {
    let mut parts: Vec<String> = relative
        .iter()
        .map(|p| p.to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().unwrap_or_default();
    let stem = last.trim_end_matches(".rs");
    if !matches!(stem, "mod" | "lib" | "main") {
        parts.push(stem.to_string());
    }
    parts
}

/// The top-level modules a file at module path `module` names in its code.
fn imports_of(
    source: &str,
    module: &[String],
    roots: &BTreeMap<String, String>,
) -> BTreeSet<String> {
    let file = syn::parse_file(source).expect("a source file of the crate parses");
    let mut reader = Imports {
        module: module.to_vec(),
        roots,
        named: BTreeSet::new(),
    };
    reader.visit_file(&file);
    reader.named
}

struct Imports<'a> {
    /// Where the code being read sits (inline `mod` blocks included).
    module: Vec<String>,
    roots: &'a BTreeMap<String, String>,
    named: BTreeSet<String>,
}

impl Imports<'_> {
    /// Resolves a path's leading segments: `crate::x` and `super::...::x` name a module.
    fn resolve(&mut self, segments: &[String]) {
        let mut at = match segments.first().map(String::as_str) {
            Some("crate") => Vec::new(),
            Some("super") => self.module.clone(),
            _ => return,
        };
        let mut rest = &segments[1.min(segments.len())..];
        if segments[0] == "super" {
            at.pop();
            while rest.first().map(String::as_str) == Some("super") {
                at.pop();
                rest = &rest[1..];
            }
        }
        let top = match (at.first(), rest.first()) {
            (Some(top), _) => top.clone(),
            (None, Some(name)) => self.roots.get(name).unwrap_or(name).clone(),
            (None, None) => return,
        };
        self.named.insert(top);
    }

    fn use_tree(&mut self, prefix: &mut Vec<String>, tree: &syn::UseTree) {
        match tree {
            syn::UseTree::Path(path) => {
                prefix.push(path.ident.to_string());
                self.use_tree(prefix, &path.tree);
                prefix.pop();
            }
            syn::UseTree::Name(name) => {
                prefix.push(name.ident.to_string());
                self.resolve(prefix);
                prefix.pop();
            }
            syn::UseTree::Rename(rename) => {
                prefix.push(rename.ident.to_string());
                self.resolve(prefix);
                prefix.pop();
            }
            syn::UseTree::Glob(_) => self.resolve(prefix),
            syn::UseTree::Group(group) => {
                for tree in &group.items {
                    self.use_tree(prefix, tree);
                }
            }
        }
    }
}

impl<'ast> Visit<'ast> for Imports<'_> {
    fn visit_item_mod(&mut self, item: &'ast syn::ItemMod) {
        self.module.push(item.ident.to_string());
        syn::visit::visit_item_mod(self, item);
        self.module.pop();
    }

    fn visit_item_use(&mut self, item: &'ast syn::ItemUse) {
        self.use_tree(&mut Vec::new(), &item.tree);
    }

    fn visit_path(&mut self, path: &'ast syn::Path) {
        let segments: Vec<String> = path.segments.iter().map(|s| s.ident.to_string()).collect();
        self.resolve(&segments);
        syn::visit::visit_path(self, path);
    }
}

fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let entries = std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    for entry in entries {
        let path = entry.expect("a directory entry").path();
        if path.is_dir() {
            files.extend(rust_files(&path));
        } else if path.extension().is_some_and(|e| e == "rs") {
            files.push(path);
        }
    }
    files.sort();
    files
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}
