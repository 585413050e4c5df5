//! The files of each crate's `src/`, their module paths, and the `use` trees and code paths in
//! each.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use crate::tokens::{is_ident, is_punct, strip_test_items, tokenize, Tok, Token};

// Files and modules

/// The workspace's crates, as directories relative to the repository ("" is the daemon, the root
/// package).
pub(crate) const CRATES: &[&str] = &["", "crates/cliffwatch-core", "crates/cliffwatch-sim"];

/// One source file of a crate's `src/`.
pub(crate) struct SourceFile {
    /// relative to the repository, e.g. `src/store/mod.rs` or
    /// `crates/cliffwatch-core/src/analysis/mod.rs`
    pub(crate) rel: String,
    /// the module path, e.g. `["store"]`; empty for `lib.rs` and `main.rs`
    pub(crate) module: Vec<String>,
    /// tokens outside `#[cfg(test)]` items
    pub(crate) toks: Vec<Token>,
}

pub(crate) fn collect_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            collect_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

pub(crate) fn module_of(rel: &str) -> Vec<String> {
    let inner = rel
        .split_once("src/")
        .unwrap()
        .1
        .strip_suffix(".rs")
        .unwrap();
    let mut parts: Vec<String> = inner.split('/').map(str::to_string).collect();
    let last = parts.last().unwrap().as_str();
    if last == "mod" || (parts.len() == 1 && (last == "lib" || last == "main")) {
        parts.pop();
    }
    parts
}

/// Every non-test file of the `src/` of the crate in `dir` (one of [`CRATES`]).
pub(crate) fn load_sources(dir: &str) -> Vec<SourceFile> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut paths = Vec::new();
    collect_files(&root.join(dir).join("src"), &mut paths);
    let mut files = Vec::new();
    let mut test_only: BTreeSet<Vec<String>> = BTreeSet::new();
    for p in &paths {
        let rel = p
            .strip_prefix(root)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        let text = std::fs::read_to_string(p).unwrap();
        let module = module_of(&rel);
        let (toks, test_mods) = strip_test_items(tokenize(&text));
        for m in test_mods {
            let mut child = module.clone();
            child.push(m);
            test_only.insert(child);
        }
        files.push(SourceFile { rel, module, toks });
    }
    // a test-only module's files, and those below it
    files.retain(|f| !test_only.iter().any(|t| f.module.starts_with(t)));
    files
}

// ---------------------------------------------------------------------------------------------
// `use` trees and paths

/// One name a `use` declaration brings in.
#[derive(Clone, Debug)]
pub(crate) struct UseItem {
    /// the path as written (`crate`, `super`, `self` or a first name, then segments)
    pub(crate) path: Vec<String>,
    /// the name it is known by here; `None` for a glob
    pub(crate) alias: Option<String>,
    pub(crate) line: usize,
}

/// Parses a use tree starting at `i`; returns the items and the index after it.
pub(crate) fn parse_use_tree(
    toks: &[Token],
    mut i: usize,
    prefix: &[String],
    out: &mut Vec<UseItem>,
) -> usize {
    let mut path = prefix.to_vec();
    if i < toks.len() && toks[i].tok == Tok::Path {
        i += 1; // a leading `::`: an external crate
        path.push("::".to_string());
    }
    loop {
        let Some(t) = toks.get(i) else { return i };
        match &t.tok {
            Tok::Punct('{') => {
                i += 1;
                loop {
                    match toks.get(i).map(|t| &t.tok) {
                        Some(Tok::Punct('}')) => return i + 1,
                        Some(Tok::Punct(',')) => i += 1,
                        None => return i,
                        _ => i = parse_use_tree(toks, i, &path, out),
                    }
                }
            }
            Tok::Punct('*') => {
                out.push(UseItem {
                    path: path.clone(),
                    alias: None,
                    line: t.line,
                });
                return i + 1;
            }
            Tok::Ident(w) => {
                let line = t.line;
                if w == "self"
                    && !path.is_empty()
                    && toks.get(i + 1).map(|t| &t.tok) != Some(&Tok::Path)
                {
                    // `{self}` or `{self as x}`
                    let mut alias = path.last().cloned();
                    i += 1;
                    if toks.get(i).is_some_and(|t| is_ident(t, "as")) {
                        if let Some(Tok::Ident(a)) = toks.get(i + 1).map(|t| &t.tok) {
                            alias = Some(a.clone());
                        }
                        i += 2;
                    }
                    out.push(UseItem {
                        path: path.clone(),
                        alias,
                        line,
                    });
                    return i;
                }
                path.push(w.clone());
                i += 1;
                if toks.get(i).map(|t| &t.tok) == Some(&Tok::Path) {
                    i += 1;
                    continue;
                }
                let mut alias = Some(w.clone());
                if toks.get(i).is_some_and(|t| is_ident(t, "as")) {
                    if let Some(Tok::Ident(a)) = toks.get(i + 1).map(|t| &t.tok) {
                        alias = if a == "_" { None } else { Some(a.clone()) };
                    }
                    i += 2;
                }
                out.push(UseItem { path, alias, line });
                return i;
            }
            _ => return i,
        }
    }
}

/// The `use` declarations of a file, and the tokens outside them.
pub(crate) fn split_uses(toks: &[Token]) -> (Vec<UseItem>, Vec<Token>) {
    let mut uses = Vec::new();
    let mut rest = Vec::new();
    let mut i = 0;
    while i < toks.len() {
        if is_ident(&toks[i], "use") {
            let j = parse_use_tree(toks, i + 1, &[], &mut uses);
            i = j;
            while i < toks.len() && !is_punct(&toks[i], ';') {
                i += 1;
            }
            i += 1;
        } else {
            rest.push(toks[i].clone());
            i += 1;
        }
    }
    (uses, rest)
}

/// The paths (`a::b::c`, two segments or more) in code outside `use` declarations.
pub(crate) fn code_paths(toks: &[Token]) -> Vec<(Vec<String>, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < toks.len() {
        let starts = matches!(&toks[i].tok, Tok::Ident(_))
            && toks.get(i + 1).map(|t| &t.tok) == Some(&Tok::Path)
            && (i == 0 || toks[i - 1].tok != Tok::Path);
        if !starts {
            i += 1;
            continue;
        }
        let line = toks[i].line;
        let mut segs = Vec::new();
        let mut j = i;
        while let Some(Tok::Ident(w)) = toks.get(j).map(|t| &t.tok) {
            segs.push(w.clone());
            if toks.get(j + 1).map(|t| &t.tok) == Some(&Tok::Path) {
                j += 2;
            } else {
                j += 1;
                break;
            }
        }
        out.push((segs, line));
        i = j.max(i + 1);
    }
    out
}

// ---------------------------------------------------------------------------------------------
