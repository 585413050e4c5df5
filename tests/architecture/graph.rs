//! Paths resolved to the files that define their items; the file and module graphs and their
//! cycles.

use std::collections::{BTreeMap, BTreeSet, HashMap, VecDeque};

use crate::sources::{code_paths, load_sources, split_uses, SourceFile, UseItem};
use crate::tokens::{is_ident, is_punct, Tok, Token};

// Resolution

pub(crate) struct Crate {
    pub(crate) files: Vec<SourceFile>,
    pub(crate) by_module: HashMap<Vec<String>, usize>,
    pub(crate) uses: Vec<Vec<UseItem>>,
    pub(crate) code: Vec<Vec<Token>>,
}

impl Crate {
    /// The crate in `dir`, one of [`crate::sources::CRATES`].
    pub(crate) fn load(dir: &str) -> Crate {
        let files = load_sources(dir);
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
    pub(crate) fn absolute(
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
    pub(crate) fn aliases(&self, k: usize) -> HashMap<String, Vec<String>> {
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
    pub(crate) fn resolve(&self, abs: &[String], depth: usize) -> Option<(usize, bool)> {
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
pub(crate) fn defines(toks: &[Token], name: &str) -> bool {
    toks.windows(2).any(|w| {
        matches!(&w[0].tok, Tok::Ident(k) if ["fn", "struct", "enum", "trait", "type", "const", "static", "union", "mod", "macro_rules"].contains(&k.as_str()))
            && matches!(&w[1].tok, Tok::Ident(n) if n == name)
    }) || toks.windows(3).any(|w| {
        is_ident(&w[0], "macro_rules") && is_punct(&w[1], '!') && is_ident(&w[2], name)
    })
}

/// A dependency of one file on another, with the first place that shows it.
#[derive(Clone, Debug)]
pub(crate) struct Evidence {
    pub(crate) line: usize,
    pub(crate) path: String,
}

pub(crate) type Graph = BTreeMap<String, BTreeMap<String, Evidence>>;

/// The file graph and the top-level module graph.
pub(crate) fn graphs(krate: &Crate) -> (Graph, Graph) {
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

pub(crate) fn add_edge(
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
pub(crate) fn cycles(g: &Graph) -> Vec<Vec<String>> {
    struct State<'a> {
        g: &'a Graph,
        index: HashMap<&'a str, usize>,
        low: HashMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on: BTreeSet<&'a str>,
        next: usize,
        out: Vec<Vec<String>>,
    }
    pub(crate) fn visit<'a>(s: &mut State<'a>, v: &'a str) {
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
pub(crate) fn shortest_cycle(g: &Graph, comp: &[String], start: &str) -> Vec<String> {
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
pub(crate) fn report(title: &str, g: &Graph) -> Vec<Vec<String>> {
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
