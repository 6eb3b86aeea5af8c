//! The crate's layout rules (README, "Architecture"), checked on its source:
//!
//! - the top-level modules of `src/` import each other without a circle (each layer imports
//!   only the layers below it): an edge `a -> b` is any `crate::b` path in a file of module
//!   `a` outside comments; the graph must be acyclic (Tarjan's strongly connected components
//!   are all single modules);
//! - `Mpc184World`'s `impl` blocks are in the facade `src/world.rs` and its child files
//!   (`src/world/*.rs`: a big `impl` split over one folder, never over sibling modules);
//! - no module but the backend names a `Backend::` variant, except where the setting is defined
//!   or parsed (`settings.rs`, the CLI `main.rs`, the deck builder).
//!
//! A failure names the modules of the circle or the offending file and line.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Every `.rs` file under `dir`.
fn sources(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).expect("src/ is readable") {
            let p = entry.expect("a directory entry").path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|e| e == "rs") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// The source without `//` comments (line and doc comments), line by line.
fn code_lines(text: &str) -> Vec<String> {
    text.lines()
        .map(|l| match l.find("//") {
            Some(i) => l[..i].to_string(),
            None => l.to_string(),
        })
        .collect()
}

/// The top-level module a file belongs to (`None` for the crate root and the binary).
fn top_module(src: &Path, file: &Path) -> Option<String> {
    let rel = file.strip_prefix(src).ok()?;
    let first = rel.components().next()?.as_os_str().to_str()?.to_string();
    let name = first.trim_end_matches(".rs").to_string();
    (name != "lib" && name != "main").then_some(name)
}

/// `crate::x` targets named on a line.
fn crate_targets(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = line;
    while let Some(i) = rest.find("crate::") {
        let tail = &rest[i + "crate::".len()..];
        let name: String = tail
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect();
        // `crate::{a, b}` lists several.
        if name.is_empty() && tail.starts_with('{') {
            let inner = &tail[1..tail.find('}').unwrap_or(tail.len())];
            for part in inner.split(',') {
                let n: String = part
                    .trim()
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                    .collect();
                if !n.is_empty() {
                    out.push(n);
                }
            }
        } else if !name.is_empty() {
            out.push(name);
        }
        rest = tail;
    }
    out
}

/// The strongly connected components with more than one module (Tarjan).
fn circles(edges: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct Tarjan<'a> {
        edges: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<String, usize>,
        low: BTreeMap<String, usize>,
        stack: Vec<String>,
        on: BTreeSet<String>,
        next: usize,
        out: Vec<Vec<String>>,
    }
    impl Tarjan<'_> {
        fn visit(&mut self, v: &str) {
            self.index.insert(v.to_string(), self.next);
            self.low.insert(v.to_string(), self.next);
            self.next += 1;
            self.stack.push(v.to_string());
            self.on.insert(v.to_string());
            let targets: Vec<String> = self
                .edges
                .get(v)
                .map(|s| s.iter().cloned().collect())
                .unwrap_or_default();
            for w in targets {
                if !self.index.contains_key(&w) {
                    self.visit(&w);
                    let lw = self.low[&w];
                    let lv = self.low.get_mut(v).expect("visited");
                    *lv = (*lv).min(lw);
                } else if self.on.contains(&w) {
                    let iw = self.index[&w];
                    let lv = self.low.get_mut(v).expect("visited");
                    *lv = (*lv).min(iw);
                }
            }
            if self.low[v] == self.index[v] {
                let mut comp = Vec::new();
                while let Some(w) = self.stack.pop() {
                    self.on.remove(&w);
                    let done = w == v;
                    comp.push(w);
                    if done {
                        break;
                    }
                }
                if comp.len() > 1 {
                    comp.sort();
                    self.out.push(comp);
                }
            }
        }
    }
    let mut t = Tarjan {
        edges,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        next: 0,
        out: Vec::new(),
    };
    let nodes: BTreeSet<String> = edges
        .iter()
        .flat_map(|(k, v)| std::iter::once(k.clone()).chain(v.iter().cloned()))
        .collect();
    for n in nodes {
        if !t.index.contains_key(&n) {
            t.visit(&n);
        }
    }
    t.out
}

fn src_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

#[test]
fn top_level_modules_import_each_other_without_a_circle() {
    let src = src_dir();
    let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for file in sources(&src) {
        let Some(me) = top_module(&src, &file) else {
            continue;
        };
        let text = std::fs::read_to_string(&file).expect("a readable source file");
        let set = edges.entry(me.clone()).or_default();
        for line in code_lines(&text) {
            for t in crate_targets(&line) {
                if t != me {
                    set.insert(t);
                }
            }
        }
    }
    assert!(
        edges.len() > 10,
        "the scan found only {} modules: is src/ where it should be?",
        edges.len()
    );
    let found = circles(&edges);
    assert!(
        found.is_empty(),
        "module circles (each list imports itself through the others): {found:?}"
    );
}

#[test]
fn the_world_impl_lives_in_the_facade_and_its_folder() {
    let src = src_dir();
    let mut places = Vec::new();
    for file in sources(&src) {
        let text = std::fs::read_to_string(&file).expect("a readable source file");
        for (n, line) in code_lines(&text).iter().enumerate() {
            if line.trim_start().starts_with("impl Mpc184World") {
                places.push((file.clone(), n + 1));
            }
        }
    }
    let facade = src.join("world.rs");
    assert!(
        places.iter().any(|(f, _)| *f == facade),
        "no impl Mpc184World in src/world.rs: {places:?}"
    );
    let stray: Vec<_> = places
        .iter()
        .filter(|(f, _)| *f != facade && !f.starts_with(src.join("world")))
        .collect();
    assert!(
        stray.is_empty(),
        "impl Mpc184World outside src/world.rs and src/world/: {stray:?}"
    );
}

#[test]
fn only_the_backend_module_names_a_backend_variant() {
    let src = src_dir();
    let allowed = ["backend", "settings", "main", "deck"];
    let mut offending = Vec::new();
    for file in sources(&src) {
        let top = top_module(&src, &file).unwrap_or_else(|| "main".into());
        if allowed.contains(&top.as_str()) {
            continue;
        }
        let text = std::fs::read_to_string(&file).expect("a readable source file");
        for (n, line) in code_lines(&text).iter().enumerate() {
            for variant in ["Lagrange", "RapierImpulse", "RapierMultibody"] {
                if line.contains(&format!("Backend::{variant}")) {
                    offending.push(format!("{}:{}: {}", file.display(), n + 1, line.trim()));
                }
            }
        }
    }
    assert!(
        offending.is_empty(),
        "Backend variants named outside the backend module: {offending:#?}"
    );
}
