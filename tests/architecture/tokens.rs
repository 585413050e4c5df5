//! Rust source as tokens: identifiers, `::`, punctuation and strings, without comments and
//! without `#[cfg(test)]` items.

#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Tok {
    Ident(String),
    /// `::`
    Path,
    Punct(char),
    Str(String),
}

#[derive(Clone, Debug)]
pub(crate) struct Token {
    pub(crate) tok: Tok,
    pub(crate) line: usize,
}

/// Splits Rust source into identifiers, `::`, punctuation and string literals, without comments.
pub(crate) fn tokenize(src: &str) -> Vec<Token> {
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
pub(crate) fn raw_string_start(c: &[char], i: usize) -> Option<(usize, usize)> {
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

pub(crate) fn is_ident(t: &Token, s: &str) -> bool {
    matches!(&t.tok, Tok::Ident(w) if w == s)
}

pub(crate) fn is_punct(t: &Token, p: char) -> bool {
    t.tok == Tok::Punct(p)
}

/// The index just past the group that opens at `i` (`(`, `[` or `{`).
pub(crate) fn skip_group(toks: &[Token], i: usize) -> usize {
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
pub(crate) fn is_cfg_test(toks: &[Token], i: usize) -> bool {
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
pub(crate) fn strip_test_items(toks: Vec<Token>) -> (Vec<Token>, Vec<String>) {
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
