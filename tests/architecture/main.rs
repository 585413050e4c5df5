//! The house rules of each crate's `src/` (the daemon, `crates/cliffwatch-core`,
//! `crates/cliffwatch-sim`), read from the source text (no build of the crate is needed):
//!
//! 1. no import cycle between top-level modules, nor between files, in any crate, counting every
//!    path that
//!    starts with `crate::`, `super::`, `self::`, `cliffwatch::` (the binary's name for the
//!    library), a child module's name, or a name a `use` brought in, outside `#[cfg(test)]` items;
//! 2. no `sqlx` (nor `libsqlite3_sys`) and no SQL text outside `src/store`, read the same way;
//! 3. no Rust file in `src/`, `tests/`, `benches/` or `examples/` of any crate over 700 lines;
//! 4. the crate boundaries: the core's and the simulator's dependency graphs (`cargo tree`, normal
//!    dependencies, default features) hold no server, database or HTTP crate, so that a library
//!    user of the core links none of them.
//!
//! A path is followed to the file that defines its item: through modules (a directory's `mod.rs`
//! or a `name.rs`) and through `use` re-exports, so a `mod.rs` that only re-exports is no hub of
//! cycles. A path that names only a module (`use crate::store;`) makes no edge of its own; the
//! items reached through it do.
//!
//! Each test prints what it found (run with `--nocapture` to see it on success).

mod graph;
mod sources;
mod tokens;

use std::collections::BTreeSet;
use std::path::Path;

/// Cycles tolerated while a move that removes them is under way: each entry names the top-level
/// modules one cycle may span. Empty: no cycle is tolerated. A tolerated cycle is still printed,
/// and an entry whose cycle is gone is reported as such.
const ALLOWED_MODULE_CYCLES: &[&[&str]] = &[];

/// The longest a Rust file may be, in lines.
const MAX_LINES: usize = 700;

use graph::{graphs, report, Crate};
use sources::{collect_files, module_of, CRATES};
use tokens::Tok;

fn top_module(rel: &str) -> Option<String> {
    module_of(rel).first().cloned()
}

/// The allowed cycle that covers a component: one whose top-level modules hold all its members,
/// which span two of them or more (a cycle inside one module is no cycle between them); `key`
/// maps a node to its top-level module.
fn allowed(
    comp: &[String],
    key: impl Fn(&str) -> Option<String>,
) -> Option<&'static [&'static str]> {
    ALLOWED_MODULE_CYCLES.iter().copied().find(|set| {
        let modules: BTreeSet<Option<String>> = comp.iter().map(|n| key(n)).collect();
        modules.len() > 1
            && modules
                .iter()
                .all(|m| m.as_ref().is_some_and(|m| set.contains(&m.as_str())))
    })
}

#[test]
fn no_import_cycles() {
    let mut failures = Vec::new();
    for dir in CRATES {
        println!("crate {}:", if dir.is_empty() { "cliffwatch" } else { dir });
        failures.extend(cycles_of(&Crate::load(dir)));
    }
    assert!(
        failures.is_empty(),
        "import cycles outside ALLOWED_MODULE_CYCLES (details above):\n  {}",
        failures.join("\n  ")
    );
}

/// The cycles of one crate that [`ALLOWED_MODULE_CYCLES`] does not allow, printed with its graph.
fn cycles_of(krate: &Crate) -> Vec<String> {
    let (files, modules) = graphs(krate);
    println!("top-level module edges:");
    for (a, es) in &modules {
        println!(
            "  {a} -> {}",
            es.keys().cloned().collect::<Vec<_>>().join(", ")
        );
    }
    let module_cycles = report("top-level modules", &modules);
    let file_cycles = report("files", &files);

    for set in ALLOWED_MODULE_CYCLES {
        let present = module_cycles
            .iter()
            .any(|c| set.iter().all(|m| c.contains(&m.to_string())));
        if !present {
            println!("allowed cycle {set:?} is gone: remove it from ALLOWED_MODULE_CYCLES");
        }
    }
    let mut failures = Vec::new();
    for c in &module_cycles {
        match allowed(c, |m| Some(m.to_string())) {
            Some(set) => println!("allowed for now ({set:?}): modules {}", c.join(", ")),
            None => failures.push(format!("modules: {}", c.join(", "))),
        }
    }
    for c in &file_cycles {
        match allowed(c, top_module) {
            Some(set) => println!("allowed for now ({set:?}): files {}", c.join(", ")),
            None => failures.push(format!("files: {}", c.join(", "))),
        }
    }
    failures
}

#[test]
fn database_only_in_store() {
    let crates: Vec<Crate> = CRATES.iter().map(|dir| Crate::load(dir)).collect();
    let sql = regex::Regex::new(
        r"\b(SELECT\s[\s\S]*\bFROM|INSERT\s+INTO|UPDATE\s+\w+\s+SET|DELETE\s+FROM|CREATE\s+(TABLE|INDEX|UNIQUE)|DROP\s+(TABLE|INDEX)|ALTER\s+TABLE|PRAGMA\s+\w+|BEGIN\s+(IMMEDIATE|TRANSACTION))\b",
    )
    .unwrap();
    let mut found = Vec::new();
    for f in crates.iter().flat_map(|k| &k.files) {
        if f.rel.starts_with("src/store/") {
            continue;
        }
        for t in &f.toks {
            match &t.tok {
                Tok::Ident(w) if w == "sqlx" || w == "libsqlite3_sys" => {
                    found.push(format!("{}:{}: names `{w}`", f.rel, t.line))
                }
                Tok::Str(s) if sql.is_match(s) => {
                    found.push(format!("{}:{}: SQL text {:?}", f.rel, t.line, truncate(s)))
                }
                _ => {}
            }
        }
    }
    println!("database code outside src/store: {} place(s)", found.len());
    for f in &found {
        println!("  {f}");
    }
    assert!(
        found.is_empty(),
        "database code outside src/store:\n  {}",
        found.join("\n  ")
    );
}

fn truncate(s: &str) -> String {
    s.chars().take(60).collect()
}

#[test]
fn no_file_over_700_lines() {
    let in_src: usize = CRATES.iter().map(|dir| Crate::load(dir).files.len()).sum();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    // every file, the test-only ones too, and the tests', benchmarks' and examples' own
    let mut paths = Vec::new();
    for krate in CRATES {
        for dir in ["src", "tests", "benches", "examples"] {
            let dir = root.join(krate).join(dir);
            if dir.is_dir() {
                collect_files(&dir, &mut paths);
            }
        }
    }
    let mut longest: Vec<(usize, String)> = paths
        .iter()
        .map(|p| {
            let text = std::fs::read_to_string(p).unwrap();
            (
                text.lines().count(),
                p.strip_prefix(root).unwrap().display().to_string(),
            )
        })
        .collect();
    longest.sort_by(|a, b| b.cmp(a));
    println!(
        "{} Rust files ({} in src/ outside test modules); the longest:",
        paths.len(),
        in_src
    );
    for (n, p) in longest.iter().take(5) {
        println!("  {n:5} {p}");
    }
    let over: Vec<String> = longest
        .iter()
        .filter(|(n, _)| *n > MAX_LINES)
        .map(|(n, p)| format!("{p}: {n} lines"))
        .collect();
    assert!(
        over.is_empty(),
        "files over {MAX_LINES} lines:\n  {}",
        over.join("\n  ")
    );
}

/// Crates no library crate of the workspace may link: the async runtime, the database, HTTP and
/// the OpenAPI generator (the core's `openapi` feature, off by default, is the one way in).
const SERVER_CRATES: &[&str] = &[
    "tokio",
    "sqlx",
    "axum",
    "hyper",
    "reqwest",
    "tower",
    "tower-http",
    "utoipa",
    "maud",
    "libsqlite3-sys",
    "notify",
    "metrics",
];

#[test]
fn the_core_and_the_simulator_link_no_server_crate() {
    for package in ["cliffwatch-core", "cliffwatch-sim"] {
        let out = std::process::Command::new(env!("CARGO"))
            .args([
                "tree",
                "--offline",
                "-e",
                "normal",
                "--prefix",
                "none",
                "-p",
                package,
            ])
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .expect("cargo tree runs");
        assert!(
            out.status.success(),
            "cargo tree -p {package}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let tree = String::from_utf8(out.stdout).unwrap();
        let names: BTreeSet<&str> = tree
            .lines()
            .filter_map(|l| l.split_whitespace().next())
            .collect();
        println!("{package}: {} packages in its graph", names.len());
        assert!(names.contains(package), "{tree}");
        let server: Vec<&&str> = SERVER_CRATES
            .iter()
            .filter(|c| names.contains(**c))
            .collect();
        assert!(server.is_empty(), "{package} links {server:?}:\n{tree}");
    }
}
