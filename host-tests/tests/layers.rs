//! The layering check of issue 13 item 2: data flows one way, bytes → frames → FDL → DP →
//! DP-V1 → profile → DPM → card (ARCHITECTURE.md), so a lower layer never names a higher one
//! outside its tests.
//!
//! The check walks the library's module tree from the crate roots in [`ROOTS`] with `syn`
//! (following `mod` declarations, skipping every item under `#[cfg(test)]` or
//! `#[cfg(any(test, …))]`, which is test support), collects every `crate::…` path (in `use`
//! trees and in expressions and types, `super::` chains resolved) and maps each to the
//! top-level module it names. Each module has a rank in [`LAYERS`]; an edge from a module to a
//! higher-ranked one is a violation.
//!
//! The violations that exist today are listed in [`KNOWN_DEBT`]: the check fails on any edge
//! that is not in the list (a new upward import) **and** on a listed edge that has gone (so the
//! list only shrinks). Run: `cargo test -p host-tests --target x86_64-unknown-linux-gnu --test layers`.
//!
//! `time` and `fdl` are the crate `pbcard-fdl` (`crates/fdl`), `dp` and `dpv1` the crate
//! `pbcard-dp` (`crates/dp`, on `pbcard-fdl`), `phy`, `led`, `node`, `store` and `fast` the crate
//! `pbcard-link` (`crates/link`, on both), `profile` the crate `pbcard-profile` (`crates/profile`,
//! on those three), `dpm` the crate `pbcard-dpm` (`crates/dpm`, on the profile), all re-exported by `src/lib.rs` (a `pub use`,
//! not a `mod`, so the walk starts again at each crate's root): Cargo keeps each crate from
//! naming anything above it; their ranks here still place the paths the modules above use
//! (`crate::fdl::…`, `crate::dp::…`), and the walk of their own files checks what Cargo
//! cannot, the direction inside a crate (`dp` never names `dpv1`, `time` never `fdl`).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use syn::visit::Visit;

/// Top-level modules of the crate roots ([`ROOTS`]), lowest layer first, with their rank (equal ranks may
/// name each other). `node` and `store` sit on DP-V1 (the node composes FDL, DP and DP-V1 and
/// defines the record-handler seam; the store persists DP/DP-V1 records); `fast` wraps the
/// node; `profile` implements the record handlers; `dpm` carries the profile to the drive;
/// `card` is this product's configuration; `app` (the card), `drive` (the simulated drive) and
/// `bench` (the card with the simulated drive; `drive` and `bench` are the crate `pbcard-sim`,
/// above `pbcard`) and `testkit` are on top.
const LAYERS: &[(&str, u8)] = &[
    ("time", 0),
    ("fdl", 1),
    ("phy", 1),
    ("led", 1),
    ("dp", 2),
    ("dpv1", 3),
    ("node", 4),
    ("store", 4),
    ("fast", 5),
    ("profile", 6),
    ("dpm", 7),
    ("card", 8),
    ("drive", 9),
    ("app", 10),
    ("bench", 10),
    ("testkit", 10),
];

/// Upward imports that exist today (from, to): issue 13 item 2 removes them (configuration as
/// data instead of `card::` constants in `node` / `fast` / `store`, as `dp` takes a
/// `dp::SlaveConfig` and `dpv1` an `im::ImDevice`;
/// `Telegram` / `Family` moved from `dpm` to `profile`, `Node::process_acyclic` over the
/// application's `node::DataRecords`, `phy::line` without `node::Node`). Remove an entry when
/// its edge goes.
const KNOWN_DEBT: &[(&str, &str)] = &[];

/// The crate roots the walk starts from (relative to the workspace root): the library and the
/// crates of the stack below it, whose top-level modules it re-exports under the same names
/// (`pbcard-fdl`: `time`, `fdl`; `pbcard-dp`: `dp`, `dpv1`; `pbcard-link`: `phy`, `led`, `node`,
/// `store`, `fast` — `pbcard` adds its test-support `fast::check`; `pbcard-profile`: `profile`; `pbcard-dpm`: `dpm`; `pbcard-sim` (above `pbcard`): `drive`, `bench`; their roots bring the layers below
/// in as `crate::fdl` / `crate::time`, so a path is ranked the same in every crate).
const ROOTS: &[&str] = &[
    "src/lib.rs",
    "crates/fdl/src/lib.rs",
    "crates/dp/src/lib.rs",
    "crates/link/src/lib.rs",
    "crates/profile/src/lib.rs",
    "crates/dpm/src/lib.rs",
    "crates/sim/src/lib.rs",
];

fn rank(m: &str) -> Option<u8> {
    LAYERS.iter().find(|(n, _)| *n == m).map(|(_, r)| *r)
}

/// Whether `#[cfg(…)]` attributes make an item test-only: `test`, `all(test, …)`, or
/// `any(test, …)` (test support, such as `feature = "test-support"`).
fn test_only(attrs: &[syn::Attribute]) -> bool {
    attrs.iter().any(|a| {
        if !a.path().is_ident("cfg") {
            return false;
        }
        let Ok(list) = a.meta.require_list() else { return false };
        let s: String = list.tokens.to_string().chars().filter(|c| !c.is_whitespace()).collect();
        let listed = s.strip_prefix("any(").or_else(|| s.strip_prefix("all("));
        s == "test" || listed.is_some_and(|l| l.split([',', ')']).any(|w| w == "test"))
    })
}

/// Collects the top-level module each `crate::` / `super::` path names, from module `here`.
struct Paths<'a> {
    here: &'a [String],
    found: BTreeSet<String>,
}

impl Paths<'_> {
    fn segments(&mut self, segs: &[String]) {
        let Some(first) = segs.first() else { return };
        let target = match first.as_str() {
            "crate" => segs.get(1).cloned(),
            "super" => {
                let ups = segs.iter().take_while(|s| *s == "super").count();
                if ups >= self.here.len() {
                    segs.get(ups).cloned()
                } else {
                    self.here.first().cloned()
                }
            }
            _ => None,
        };
        if let Some(t) = target {
            self.found.insert(t);
        }
    }

    fn use_tree(&mut self, prefix: &mut Vec<String>, tree: &syn::UseTree) {
        match tree {
            syn::UseTree::Path(p) => {
                prefix.push(p.ident.to_string());
                self.use_tree(prefix, &p.tree);
                prefix.pop();
            }
            syn::UseTree::Name(n) => {
                prefix.push(n.ident.to_string());
                self.segments(prefix);
                prefix.pop();
            }
            syn::UseTree::Rename(r) => {
                prefix.push(r.ident.to_string());
                self.segments(prefix);
                prefix.pop();
            }
            syn::UseTree::Glob(_) => {
                prefix.push("*".into());
                self.segments(prefix);
                prefix.pop();
            }
            syn::UseTree::Group(g) => {
                for t in &g.items {
                    self.use_tree(prefix, t);
                }
            }
        }
    }
}

impl<'ast> Visit<'ast> for Paths<'_> {
    fn visit_item(&mut self, i: &'ast syn::Item) {
        let attrs = match i {
            syn::Item::Const(x) => &x.attrs,
            syn::Item::Enum(x) => &x.attrs,
            syn::Item::Fn(x) => &x.attrs,
            syn::Item::Impl(x) => &x.attrs,
            syn::Item::Mod(x) => &x.attrs,
            syn::Item::Static(x) => &x.attrs,
            syn::Item::Struct(x) => &x.attrs,
            syn::Item::Trait(x) => &x.attrs,
            syn::Item::Type(x) => &x.attrs,
            syn::Item::Use(x) => &x.attrs,
            syn::Item::Macro(x) => &x.attrs,
            _ => return syn::visit::visit_item(self, i),
        };
        if test_only(attrs) {
            return;
        }
        if let syn::Item::Mod(m) = i {
            if m.content.is_none() {
                return; // a file module: walked on its own
            }
        }
        if let syn::Item::Use(u) = i {
            self.use_tree(&mut Vec::new(), &u.tree);
            return;
        }
        syn::visit::visit_item(self, i);
    }

    fn visit_impl_item(&mut self, i: &'ast syn::ImplItem) {
        if let syn::ImplItem::Fn(f) = i {
            if test_only(&f.attrs) {
                return;
            }
        }
        syn::visit::visit_impl_item(self, i);
    }

    fn visit_path(&mut self, p: &'ast syn::Path) {
        let segs: Vec<String> = p.segments.iter().map(|s| s.ident.to_string()).collect();
        self.segments(&segs);
        syn::visit::visit_path(self, p);
    }
}

/// The file of module `name` declared in `file` (module path `module`).
fn child_file(file: &Path, name: &str) -> Option<PathBuf> {
    let dir = file.parent()?;
    let stem = file.file_stem()?.to_str()?;
    let base = if matches!(stem, "lib" | "mod") { dir.to_path_buf() } else { dir.join(stem) };
    [base.join(format!("{name}.rs")), base.join(name).join("mod.rs")].into_iter().find(|p| p.exists())
}

/// Walks the module tree: every non-test file module, with its module path.
fn walk(file: &Path, module: Vec<String>, out: &mut Vec<(Vec<String>, PathBuf, syn::File)>) {
    let text = std::fs::read_to_string(file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    let ast = syn::parse_file(&text).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    fn mods(items: &[syn::Item], file: &Path, module: &[String], out: &mut Vec<(Vec<String>, PathBuf, syn::File)>) {
        for item in items {
            let syn::Item::Mod(m) = item else { continue };
            if test_only(&m.attrs) {
                continue;
            }
            let mut path = module.to_vec();
            path.push(m.ident.to_string());
            match &m.content {
                Some((_, inner)) => mods(inner, file, &path, out),
                None => {
                    let child = child_file(file, &m.ident.to_string())
                        .unwrap_or_else(|| panic!("{}: no file for mod {}", file.display(), m.ident));
                    walk(&child, path, out);
                }
            }
        }
    }
    mods(&ast.items, file, &module, out);
    out.push((module, file.to_path_buf(), ast));
}

/// The workspace root.
fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Every non-test file module of every crate in [`ROOTS`], with its module path.
fn files() -> Vec<(Vec<String>, PathBuf, syn::File)> {
    let mut files = Vec::new();
    for r in ROOTS {
        walk(&workspace().join(r), Vec::new(), &mut files);
    }
    files
}

/// Every edge (from, to) between top-level modules outside tests, with the files that make it.
fn edges() -> BTreeMap<(String, String), BTreeSet<String>> {
    let root = workspace();
    let files = files();
    let mut edges: BTreeMap<(String, String), BTreeSet<String>> = BTreeMap::new();
    for (module, file, ast) in &files {
        let Some(top) = module.first() else { continue };
        let mut v = Paths { here: module, found: BTreeSet::new() };
        v.visit_file(ast);
        for t in v.found {
            if &t != top && rank(&t).is_some() {
                let rel = file.strip_prefix(&root).unwrap_or(file).display().to_string();
                edges.entry((top.clone(), t)).or_default().insert(rel);
            }
        }
    }
    edges
}

/// Every top-level module of every crate root has a layer (test-only modules, such as the
/// library's `dp_tests`, are not walked and need none).
#[test]
fn every_top_level_module_has_a_layer() {
    for r in ROOTS {
        let ast = syn::parse_file(&std::fs::read_to_string(workspace().join(r)).unwrap()).unwrap();
        for item in &ast.items {
            if let syn::Item::Mod(m) = item {
                if !test_only(&m.attrs) {
                    assert!(rank(&m.ident.to_string()).is_some(), "{r}: module {} has no layer in LAYERS", m.ident);
                }
            }
        }
    }
}

/// The walk reaches every layer's files, the crates' below the library included: each
/// non-test module of [`LAYERS`] is walked from exactly one root.
#[test]
fn the_walk_covers_every_layer() {
    let files = files();
    for (m, _) in LAYERS.iter().filter(|(m, _)| *m != "testkit") {
        let walked: BTreeSet<_> = files
            .iter()
            .filter(|(module, _, _)| module.len() == 1 && module[0] == *m)
            .map(|(_, file, _)| file.display().to_string())
            .collect();
        assert_eq!(walked.len(), 1, "module {m} is walked from {} files: {walked:?}", walked.len());
    }
    for f in [
        "crates/dp/src/dp/mod.rs",
        "crates/dp/src/dp/cfg.rs",
        "crates/dp/src/dpv1/c2.rs",
        "crates/fdl/src/fdl/station.rs",
        "crates/link/src/fast.rs",
        "crates/link/src/phy/stream.rs",
        "crates/link/src/store/mod.rs",
        "crates/profile/src/profile/mod.rs",
        "crates/profile/src/profile/cyclic.rs",
        "crates/dpm/src/dpm/mod.rs",
        "crates/dpm/src/dpm/spi.rs",
        "crates/sim/src/drive/mod.rs",
        "crates/sim/src/bench.rs",
    ] {
        assert!(files.iter().any(|(_, file, _)| file.ends_with(f)), "{f} is not walked");
    }
}

#[test]
fn no_lower_layer_imports_a_higher_one() {
    let edges = edges();
    let mut upward = BTreeMap::new();
    for ((from, to), files) in &edges {
        if rank(to) > rank(from) {
            upward.insert((from.as_str(), to.as_str()), files);
        }
    }
    println!("upward imports outside tests ({}):", upward.len());
    for ((f, t), files) in &upward {
        println!("  {f} -> {t}: {}", files.iter().cloned().collect::<Vec<_>>().join(", "));
    }
    let new: Vec<_> = upward.keys().filter(|e| !KNOWN_DEBT.contains(e)).collect();
    assert!(new.is_empty(), "new upward imports (a lower layer names a higher one): {new:?}");
    let gone: Vec<_> = KNOWN_DEBT.iter().filter(|e| !upward.contains_key(*e)).collect();
    assert!(gone.is_empty(), "edges in KNOWN_DEBT that no longer exist, remove them: {gone:?}");
}

/// The checker itself: a test-only import is not an edge, a `super::super::` climb is.
#[test]
fn the_checker_sees_imports_and_skips_tests() {
    let ast = syn::parse_file(
        "use crate::card::X; fn f() { super::super::dpm::g(); } \
         #[cfg(test)] mod tests { use crate::app::A; } #[cfg(all(test, feature = \"x\"))] fn g() { crate::led::l(); } #[cfg(not(test))] fn h() { crate::drive::d(); }",
    )
    .unwrap();
    let here = vec!["dp".to_string(), "cfg".to_string()];
    let mut v = Paths { here: &here, found: BTreeSet::new() };
    v.visit_file(&ast);
    let found: Vec<_> = v.found.iter().map(String::as_str).collect();
    assert_eq!(found, ["card", "dpm", "drive"]);
}
