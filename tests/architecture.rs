//! The house rules of `src/`, read from the source text (no build of the crate is needed):
//!
//! 1. no import cycle between top-level modules, nor between files, counting every path that
//!    starts with `crate::`, `super::`, `self::`, `cliffwatch::` (the binary's name for the
//!    library), a child module's name, or a name a `use` brought in, outside `#[cfg(test)]` items;
//! 2. no `sqlx` (nor `libsqlite3_sys`) and no SQL text outside `src/store`, read the same way;
//! 3. no file in `src/` over 700 lines.
//!
//! A path is followed to the file that defines its item: through modules (a directory's `mod.rs`
//! or a `name.rs`) and through `use` re-exports, so a `mod.rs` that only re-exports is no hub of
//! cycles. A path that names only a module (`use crate::store;`) makes no edge of its own; the
//! items reached through it do.
//!
//! Each test prints what it found (run with `--nocapture` to see it on success).

use std::collections::{BTreeMap, BTreeSet, HashMap, VecDeque};
use std::path::{Path, PathBuf};

/// Cycles tolerated while a move that removes them is under way: each entry names the top-level
/// modules one cycle may span. Empty: no cycle is tolerated. A tolerated cycle is still printed,
/// and an entry whose cycle is gone is reported as such.
const ALLOWED_MODULE_CYCLES: &[&[&str]] = &[];

/// The longest a file in `src/` may be, in lines.
const MAX_LINES: usize = 700;

// ---------------------------------------------------------------------------------------------
// Tokens

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Ident(String),
    /// `::`
    Path,
    Punct(char),
    Str(String),
}

#[derive(Clone, Debug)]
struct Token {
    tok: Tok,
    line: usize,
}

/// Splits Rust source into identifiers, `::`, punctuation and string literals, without comments.
fn tokenize(src: &str) -> Vec<Token> {
    let c: Vec<char> = src.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    let mut line = 1;
    let n = c.len();
    while i < n {
        let ch = c[i];
        if ch == '\n' {
            line += 1;
            i += 1;
        } else if ch.is_whitespace() {
            i += 1;
        } else if ch == '/' && i + 1 < n && c[i + 1] == '/' {
            while i < n && c[i] != '\n' {
                i += 1;
            }
        } else if ch == '/' && i + 1 < n && c[i + 1] == '*' {
            let mut depth = 0;
            while i < n {
                if c[i] == '/' && i + 1 < n && c[i + 1] == '*' {
                    depth += 1;
                    i += 2;
                } else if c[i] == '*' && i + 1 < n && c[i + 1] == '/' {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    if c[i] == '\n' {
                        line += 1;
                    }
                    i += 1;
                }
            }
        } else if let Some((len, hashes)) = raw_string_start(&c, i) {
            // r"..", r#".."#, br#".."#
            let start_line = line;
            let mut j = i + len;
            let mut s = String::new();
            loop {
                if j >= n {
                    break;
                }
                if c[j] == '"' && (0..hashes).all(|k| j + 1 + k < n && c[j + 1 + k] == '#') {
                    j += 1 + hashes;
                    break;
                }
                if c[j] == '\n' {
                    line += 1;
                }
                s.push(c[j]);
                j += 1;
            }
            out.push(Token {
                tok: Tok::Str(s),
                line: start_line,
            });
            i = j;
        } else if ch == '"' || ((ch == 'b' || ch == 'c') && i + 1 < n && c[i + 1] == '"') {
            let start_line = line;
            let mut j = if ch == '"' { i + 1 } else { i + 2 };
            let mut s = String::new();
            while j < n && c[j] != '"' {
                if c[j] == '\\' && j + 1 < n {
                    if c[j + 1] == '\n' {
                        line += 1;
                    }
                    s.push(c[j + 1]);
                    j += 2;
                    continue;
                }
                if c[j] == '\n' {
                    line += 1;
                }
                s.push(c[j]);
                j += 1;
            }
            out.push(Token {
                tok: Tok::Str(s),
                line: start_line,
            });
            i = j + 1;
        } else if ch == '\'' || (ch == 'b' && i + 1 < n && c[i + 1] == '\'') {
            // a char literal, or a lifetime / label
            let k = if ch == 'b' { i + 1 } else { i };
            if k + 1 < n && c[k + 1] == '\\' {
                let mut j = k + 2;
                while j < n && c[j] != '\'' {
                    j += 1;
                }
                i = j + 1;
            } else if k + 2 < n && c[k + 2] == '\'' {
                i = k + 3;
            } else {
                // lifetime: skip the quote, the name follows as an identifier
                i = k + 1;
            }
        } else if ch.is_alphanumeric() || ch == '_' {
            let mut j = i;
            while j < n && (c[j].is_alphanumeric() || c[j] == '_') {
                j += 1;
            }
            let mut word: String = c[i..j].iter().collect();
            if let Some(raw) = word.strip_prefix("r#") {
                word = raw.to_string();
            }
            // `r#ident`
            if word == "r" && j < n && c[j] == '#' && j + 1 < n && c[j + 1].is_alphabetic() {
                let mut k = j + 1;
                while k < n && (c[k].is_alphanumeric() || c[k] == '_') {
                    k += 1;
                }
                word = c[j + 1..k].iter().collect();
                j = k;
            }
            out.push(Token {
                tok: Tok::Ident(word),
                line,
            });
            i = j;
        } else if ch == ':' && i + 1 < n && c[i + 1] == ':' {
            out.push(Token {
                tok: Tok::Path,
                line,
            });
            i += 2;
        } else {
            out.push(Token {
                tok: Tok::Punct(ch),
                line,
            });
            i += 1;
        }
    }
    out
}

/// When a raw string starts at `i`: the length of its opening (`r#"`) and its number of `#`.
fn raw_string_start(c: &[char], i: usize) -> Option<(usize, usize)> {
    if i > 0 && (c[i - 1].is_alphanumeric() || c[i - 1] == '_') {
        return None;
    }
    let mut j = i;
    if c.get(j) == Some(&'b') || c.get(j) == Some(&'c') {
        j += 1;
    }
    if c.get(j) != Some(&'r') {
        return None;
    }
    j += 1;
    let mut hashes = 0;
    while c.get(j) == Some(&'#') {
        hashes += 1;
        j += 1;
    }
    if c.get(j) == Some(&'"') {
        Some((j + 1 - i, hashes))
    } else {
        None
    }
}

fn is_ident(t: &Token, s: &str) -> bool {
    matches!(&t.tok, Tok::Ident(w) if w == s)
}

fn is_punct(t: &Token, p: char) -> bool {
    t.tok == Tok::Punct(p)
}

/// The index just past the group that opens at `i` (`(`, `[` or `{`).
fn skip_group(toks: &[Token], i: usize) -> usize {
    let mut depth = 0i32;
    let mut j = i;
    while j < toks.len() {
        match toks[j].tok {
            Tok::Punct('(') | Tok::Punct('[') | Tok::Punct('{') => depth += 1,
            Tok::Punct(')') | Tok::Punct(']') | Tok::Punct('}') => {
                depth -= 1;
                if depth == 0 {
                    return j + 1;
                }
            }
            _ => {}
        }
        j += 1;
    }
    toks.len()
}

/// Whether the attribute starting at `i` (`#`) is exactly `#[cfg(test)]`.
fn is_cfg_test(toks: &[Token], i: usize) -> bool {
    let want = ["#", "[", "cfg", "(", "test", ")", "]"];
    want.iter().enumerate().all(|(k, w)| {
        toks.get(i + k).is_some_and(|t| match &t.tok {
            Tok::Ident(s) => s == w,
            Tok::Punct(p) => w.len() == 1 && w.starts_with(*p),
            _ => false,
        })
    })
}

/// Removes every item under `#[cfg(test)]`; returns the rest and the names of the test-only file
/// modules (`#[cfg(test)] mod name;`).
fn strip_test_items(toks: Vec<Token>) -> (Vec<Token>, Vec<String>) {
    let mut out = Vec::with_capacity(toks.len());
    let mut test_mods = Vec::new();
    let mut i = 0;
    while i < toks.len() {
        if is_cfg_test(&toks, i) {
            let mut j = i + 7;
            // further attributes
            while j + 1 < toks.len() && is_punct(&toks[j], '#') && is_punct(&toks[j + 1], '[') {
                j = skip_group(&toks, j + 1);
            }
            let item_start = j;
            // the item: up to `;` or a `{ … }` at depth 0
            while j < toks.len() {
                match toks[j].tok {
                    Tok::Punct(';') => {
                        j += 1;
                        break;
                    }
                    Tok::Punct('{') => {
                        j = skip_group(&toks, j);
                        break;
                    }
                    Tok::Punct('(') | Tok::Punct('[') => j = skip_group(&toks, j),
                    _ => j += 1,
                }
            }
            let item = &toks[item_start..j];
            if let Some(m) = item.iter().position(|t| is_ident(t, "mod")) {
                if is_punct(item.last().unwrap(), ';') {
                    if let Some(Tok::Ident(name)) = item.get(m + 1).map(|t| &t.tok) {
                        test_mods.push(name.clone());
                    }
                }
            }
            i = j;
        } else {
            out.push(toks[i].clone());
            i += 1;
        }
    }
    (out, test_mods)
}

// ---------------------------------------------------------------------------------------------
// Files and modules

/// One source file of `src/`.
struct SourceFile {
    /// relative to the repository, e.g. `src/store/mod.rs`
    rel: String,
    /// the module path, e.g. `["store"]`; empty for `lib.rs` and `main.rs`
    module: Vec<String>,
    /// tokens outside `#[cfg(test)]` items
    toks: Vec<Token>,
}

fn collect_files(dir: &Path, out: &mut Vec<PathBuf>) {
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

fn module_of(rel: &str) -> Vec<String> {
    let inner = rel
        .strip_prefix("src/")
        .unwrap()
        .strip_suffix(".rs")
        .unwrap();
    let mut parts: Vec<String> = inner.split('/').map(str::to_string).collect();
    let last = parts.last().unwrap().as_str();
    if last == "mod" || (parts.len() == 1 && (last == "lib" || last == "main")) {
        parts.pop();
    }
    parts
}

/// Every non-test file of `src/`.
fn load_sources() -> Vec<SourceFile> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut paths = Vec::new();
    collect_files(&root.join("src"), &mut paths);
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
struct UseItem {
    /// the path as written (`crate`, `super`, `self` or a first name, then segments)
    path: Vec<String>,
    /// the name it is known by here; `None` for a glob
    alias: Option<String>,
    line: usize,
}

/// Parses a use tree starting at `i`; returns the items and the index after it.
fn parse_use_tree(
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
fn split_uses(toks: &[Token]) -> (Vec<UseItem>, Vec<Token>) {
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
fn code_paths(toks: &[Token]) -> Vec<(Vec<String>, usize)> {
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
// Resolution

struct Crate {
    files: Vec<SourceFile>,
    by_module: HashMap<Vec<String>, usize>,
    uses: Vec<Vec<UseItem>>,
    code: Vec<Vec<Token>>,
}

impl Crate {
    fn load() -> Crate {
        let files = load_sources();
        let mut by_module = HashMap::new();
        for (k, f) in files.iter().enumerate() {
            if !f.module.is_empty() {
                by_module.insert(f.module.clone(), k);
            }
        }
        let mut uses = Vec::new();
        let mut code = Vec::new();
        for f in &files {
            let (u, c) = split_uses(&f.toks);
            uses.push(u);
            code.push(c);
        }
        Crate {
            files,
            by_module,
            uses,
            code,
        }
    }

    /// The absolute module path a path written in module `here` means, or `None` for another
    /// crate's path.
    fn absolute(
        &self,
        here: &[String],
        path: &[String],
        local: &HashMap<String, Vec<String>>,
    ) -> Option<Vec<String>> {
        let first = path.first()?.as_str();
        let mut base: Vec<String>;
        let mut k = 0;
        match first {
            "crate" | "cliffwatch" => {
                base = Vec::new();
                k = 1;
            }
            "self" => {
                base = here.to_vec();
                k = 1;
            }
            "super" => {
                base = here.to_vec();
                while path.get(k).map(String::as_str) == Some("super") {
                    base.pop()?;
                    k += 1;
                }
            }
            "::" => return None,
            name => {
                let mut child = here.to_vec();
                child.push(name.to_string());
                if let Some(target) = local.get(name) {
                    base = target.clone();
                    k = 1;
                } else if self.by_module.contains_key(&child) {
                    base = here.to_vec();
                } else {
                    return None;
                }
            }
        }
        base.extend(path[k..].iter().cloned());
        Some(base)
    }

    /// The names a file's `use` declarations bring in, as absolute paths inside the crate.
    fn aliases(&self, k: usize) -> HashMap<String, Vec<String>> {
        let here = &self.files[k].module;
        let mut map = HashMap::new();
        for u in &self.uses[k] {
            if let (Some(alias), Some(abs)) =
                (&u.alias, self.absolute(here, &u.path, &HashMap::new()))
            {
                map.insert(alias.clone(), abs);
            }
        }
        map
    }

    /// The file that defines what the absolute path names, and whether the path named only a
    /// module.
    fn resolve(&self, abs: &[String], depth: usize) -> Option<(usize, bool)> {
        let mut module: Vec<String> = Vec::new();
        let mut file = None;
        for (i, seg) in abs.iter().enumerate() {
            let mut child = module.clone();
            child.push(seg.clone());
            if let Some(&f) = self.by_module.get(&child) {
                module = child;
                file = Some(f);
                continue;
            }
            // `seg` is an item of `module`: follow a `use` that brought it there
            let f = file?;
            if depth < 16 {
                for u in &self.uses[f] {
                    let hit = match &u.alias {
                        Some(a) => a == seg,
                        None => false,
                    };
                    if hit {
                        if let Some(mut target) = self.absolute(&module, &u.path, &HashMap::new()) {
                            target.extend(abs[i + 1..].iter().cloned());
                            return self.resolve(&target, depth + 1);
                        }
                        // another crate's item
                        return Some((f, false));
                    }
                }
                // a glob re-export whose module defines the name
                if !defines(&self.code[f], seg) {
                    for u in self.uses[f].iter().filter(|u| u.alias.is_none()) {
                        if let Some(mut target) = self.absolute(&module, &u.path, &HashMap::new()) {
                            target.push(seg.clone());
                            if let Some((g, only_module)) = self.resolve(&target, depth + 1) {
                                if g != f && defines(&self.code[g], seg) {
                                    return Some((g, only_module));
                                }
                            }
                        }
                    }
                }
            }
            return Some((f, false));
        }
        file.map(|f| (f, true))
    }
}

/// Whether the tokens define an item of that name.
fn defines(toks: &[Token], name: &str) -> bool {
    toks.windows(2).any(|w| {
        matches!(&w[0].tok, Tok::Ident(k) if ["fn", "struct", "enum", "trait", "type", "const", "static", "union", "mod", "macro_rules"].contains(&k.as_str()))
            && matches!(&w[1].tok, Tok::Ident(n) if n == name)
    }) || toks.windows(3).any(|w| {
        is_ident(&w[0], "macro_rules") && is_punct(&w[1], '!') && is_ident(&w[2], name)
    })
}

/// A dependency of one file on another, with the first place that shows it.
#[derive(Clone, Debug)]
struct Evidence {
    line: usize,
    path: String,
}

type Graph = BTreeMap<String, BTreeMap<String, Evidence>>;

/// The file graph and the top-level module graph.
fn graphs(krate: &Crate) -> (Graph, Graph) {
    let mut files: Graph = BTreeMap::new();
    let mut modules: Graph = BTreeMap::new();
    for (k, f) in krate.files.iter().enumerate() {
        files.entry(f.rel.clone()).or_default();
        let local = krate.aliases(k);
        let mut refs: Vec<(Vec<String>, usize)> = Vec::new();
        for u in &krate.uses[k] {
            if let Some(abs) = krate.absolute(&f.module, &u.path, &HashMap::new()) {
                // a glob names the module's items: an edge to the module
                let glob = u.alias.is_none();
                refs.push((abs.clone(), u.line));
                if glob {
                    if let Some((g, _)) = krate.resolve(&abs, 0) {
                        add_edge(krate, &mut files, &mut modules, k, g, u.line, &u.path);
                    }
                }
            }
        }
        for (path, line) in code_paths(&krate.code[k]) {
            if let Some(abs) = krate.absolute(&f.module, &path, &local) {
                refs.push((abs, line));
            }
        }
        for (abs, line) in refs {
            if let Some((g, only_module)) = krate.resolve(&abs, 0) {
                if !only_module {
                    add_edge(krate, &mut files, &mut modules, k, g, line, &abs);
                }
            }
        }
    }
    (files, modules)
}

fn add_edge(
    krate: &Crate,
    files: &mut Graph,
    modules: &mut Graph,
    from: usize,
    to: usize,
    line: usize,
    path: &[String],
) {
    if from == to {
        return;
    }
    let (a, b) = (&krate.files[from], &krate.files[to]);
    let ev = Evidence {
        line,
        path: path.join("::"),
    };
    files
        .entry(a.rel.clone())
        .or_default()
        .entry(b.rel.clone())
        .or_insert_with(|| ev.clone());
    if let (Some(ma), Some(mb)) = (a.module.first(), b.module.first()) {
        if ma != mb {
            modules
                .entry(ma.clone())
                .or_default()
                .entry(mb.clone())
                .or_insert_with(|| Evidence {
                    line,
                    path: format!("{}: {}", a.rel, ev.path),
                });
        }
    }
}

/// The strongly connected components with more than one member (Tarjan).
fn cycles(g: &Graph) -> Vec<Vec<String>> {
    struct State<'a> {
        g: &'a Graph,
        index: HashMap<&'a str, usize>,
        low: HashMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on: BTreeSet<&'a str>,
        next: usize,
        out: Vec<Vec<String>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a str) {
        s.index.insert(v, s.next);
        s.low.insert(v, s.next);
        s.next += 1;
        s.stack.push(v);
        s.on.insert(v);
        if let Some(es) = s.g.get(v) {
            for w in es.keys() {
                let w = w.as_str();
                if !s.index.contains_key(w) {
                    visit(s, w);
                    let l = s.low[v].min(s.low[w]);
                    s.low.insert(v, l);
                } else if s.on.contains(w) {
                    let l = s.low[v].min(s.index[w]);
                    s.low.insert(v, l);
                }
            }
        }
        if s.low[v] == s.index[v] {
            let mut comp = Vec::new();
            loop {
                let w = s.stack.pop().unwrap();
                s.on.remove(w);
                comp.push(w.to_string());
                if w == v {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                s.out.push(comp);
            }
        }
    }
    let mut s = State {
        g,
        index: HashMap::new(),
        low: HashMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        next: 0,
        out: Vec::new(),
    };
    for v in g.keys() {
        if !s.index.contains_key(v.as_str()) {
            visit(&mut s, v);
        }
    }
    s.out.sort();
    s.out
}

/// One shortest cycle through `start` inside the component.
fn shortest_cycle(g: &Graph, comp: &[String], start: &str) -> Vec<String> {
    let inside: BTreeSet<&str> = comp.iter().map(String::as_str).collect();
    let mut prev: HashMap<&str, &str> = HashMap::new();
    let mut queue = VecDeque::from([start]);
    while let Some(v) = queue.pop_front() {
        for w in g.get(v).into_iter().flat_map(|e| e.keys()) {
            let w = w.as_str();
            if !inside.contains(w) {
                continue;
            }
            if w == start {
                let mut path = vec![v.to_string()];
                let mut x = v;
                while x != start {
                    x = prev[x];
                    path.push(x.to_string());
                }
                path.reverse();
                path.push(start.to_string());
                return path;
            }
            if !prev.contains_key(w) {
                prev.insert(w, v);
                queue.push_back(w);
            }
        }
    }
    Vec::new()
}

/// Prints the components and their edges; returns them.
fn report(title: &str, g: &Graph) -> Vec<Vec<String>> {
    let comps = cycles(g);
    let edges: usize = g.values().map(BTreeMap::len).sum();
    println!(
        "{title}: {} nodes, {edges} edges, {} cycle(s)",
        g.len(),
        comps.len()
    );
    for comp in &comps {
        println!("  cycle among {}:", comp.join(", "));
        println!(
            "    e.g. {}",
            shortest_cycle(g, comp, &comp[0]).join(" -> ")
        );
        for a in comp {
            for (b, ev) in g.get(a).into_iter().flatten() {
                if comp.contains(b) {
                    println!("    {a} -> {b}   (line {}: {})", ev.line, ev.path);
                }
            }
        }
    }
    comps
}

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
    let krate = Crate::load();
    let (files, modules) = graphs(&krate);
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
    assert!(
        failures.is_empty(),
        "import cycles outside ALLOWED_MODULE_CYCLES (details above):\n  {}",
        failures.join("\n  ")
    );
}

#[test]
fn database_only_in_store() {
    let krate = Crate::load();
    let sql = regex::Regex::new(
        r"\b(SELECT\s[\s\S]*\bFROM|INSERT\s+INTO|UPDATE\s+\w+\s+SET|DELETE\s+FROM|CREATE\s+(TABLE|INDEX|UNIQUE)|DROP\s+(TABLE|INDEX)|ALTER\s+TABLE|PRAGMA\s+\w+|BEGIN\s+(IMMEDIATE|TRANSACTION))\b",
    )
    .unwrap();
    let mut found = Vec::new();
    for f in &krate.files {
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
    let krate = Crate::load();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    // every file, the test-only ones too
    let mut paths = Vec::new();
    collect_files(&root.join("src"), &mut paths);
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
        "{} files in src/ ({} outside test modules); the longest:",
        paths.len(),
        krate.files.len()
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
