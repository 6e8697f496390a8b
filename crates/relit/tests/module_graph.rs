//! The top-level modules of crate `relit` form a DAG that follows the data: spheres,
//! colours and cameras at the bottom; images, bases, storage and maps above them; files
//! (`codec`) above those; environments, lights and the engine next; fitting, evaluation,
//! capture and synthesis on top. This test reads `src/` and fails, naming the cycle and
//! where each of its references is, when a module refers to one that refers back to it.
//!
//! The rule: module `a` refers to module `b` when a file of `a` (`src/a.rs` or under
//! `src/a/`) holds a path that reaches `b`:
//!
//! * `crate::b…`, a `crate::{b…, …}` group, or `crate::X` for an item the crate root
//!   re-exports from `b` (`pub use b::X` in `lib.rs`);
//! * `super::…` that climbs out of `a` to the crate root and then into `b`;
//! * in code, test code included (`#[cfg(test)]` modules and files), **and in doc
//!   comments** (`///`, `//!`): a doc link or path is knowledge of the module it names,
//!   and a module's docs should not lean on what is built on top of it. Ordinary
//!   comments (`//`, `/* */`) and string literals do not count.
//!
//! `lib.rs` itself (which declares every module) is not a node.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Where a reference was found, for the failure message.
#[derive(Clone, Debug)]
struct Site {
    file: PathBuf,
    line: usize,
}

/// `text` with ordinary comments, string and char literals blanked to spaces (newlines
/// kept, so line numbers hold); doc comments are kept.
fn strip(text: &str) -> String {
    let c: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let blank = |ch: char| if ch == '\n' { '\n' } else { ' ' };
    let mut i = 0;
    while i < c.len() {
        let at = |k: usize| c.get(i + k).copied().unwrap_or('\0');
        if at(0) == '/' && at(1) == '/' {
            let doc = at(2) == '!' || (at(2) == '/' && at(3) != '/');
            while i < c.len() && c[i] != '\n' {
                out.push(if doc { c[i] } else { ' ' });
                i += 1;
            }
        } else if at(0) == '/' && at(1) == '*' {
            let mut depth = 0;
            while i < c.len() {
                if c[i] == '/' && c.get(i + 1) == Some(&'*') {
                    depth += 1;
                    out.push_str("  ");
                    i += 2;
                } else if c[i] == '*' && c.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    out.push_str("  ");
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    out.push(blank(c[i]));
                    i += 1;
                }
            }
        } else if at(0) == '"' || (at(0) == 'r' && (at(1) == '"' || at(1) == '#')) {
            // A string, raw or not (`r` preceded by an identifier character is not one).
            let ident_before = i > 0 && (c[i - 1].is_alphanumeric() || c[i - 1] == '_');
            if at(0) == 'r' && ident_before {
                out.push(c[i]);
                i += 1;
                continue;
            }
            let raw = at(0) == 'r';
            let mut hashes = 0;
            if raw {
                out.push(' ');
                i += 1;
                while c.get(i) == Some(&'#') {
                    hashes += 1;
                    out.push(' ');
                    i += 1;
                }
                if c.get(i) != Some(&'"') {
                    continue;
                }
            }
            out.push(' ');
            i += 1;
            while i < c.len() {
                if !raw && c[i] == '\\' {
                    out.push(' ');
                    out.push(blank(c.get(i + 1).copied().unwrap_or(' ')));
                    i += 2;
                    continue;
                }
                if c[i] == '"' && (0..hashes).all(|h| c.get(i + 1 + h) == Some(&'#')) {
                    for _ in 0..=hashes {
                        out.push(' ');
                    }
                    i += 1 + hashes;
                    break;
                }
                out.push(blank(c[i]));
                i += 1;
            }
        } else if at(0) == '\'' && (at(1) == '\\' || (at(1) != '\0' && at(2) == '\'')) {
            // A char literal (a lifetime has no closing quote after one character).
            out.push(' ');
            i += 1;
            while i < c.len() && c[i] != '\'' {
                if c[i] == '\\' {
                    out.push(' ');
                    i += 1;
                }
                out.push(' ');
                i += 1;
            }
            out.push(' ');
            i += 1;
        } else {
            out.push(c[i]);
            i += 1;
        }
    }
    out
}

fn is_ident(ch: char) -> bool {
    ch.is_alphanumeric() || ch == '_'
}

/// The identifier at the start of `s` (after spaces).
fn ident(s: &str) -> &str {
    let s = s.trim_start();
    let end = s.find(|ch: char| !is_ident(ch)).unwrap_or(s.len());
    &s[..end]
}

/// The first segments of the paths in a `{…}` group at the start of `s`.
fn group_heads(s: &str) -> Vec<String> {
    let mut heads = Vec::new();
    let mut depth = 0;
    let mut expect = true;
    for (k, ch) in s.char_indices() {
        match ch {
            '{' => {
                depth += 1;
                if depth == 1 {
                    expect = true;
                    continue;
                }
            }
            '}' => {
                depth -= 1;
                if depth == 0 {
                    break;
                }
            }
            ',' if depth == 1 => expect = true,
            _ => {}
        }
        if depth == 1 && expect && is_ident(ch) {
            heads.push(ident(&s[k..]).to_string());
            expect = false;
        }
    }
    heads
}

/// The crate's top-level modules and the module each root re-export comes from.
fn root(src: &Path) -> (BTreeSet<String>, BTreeMap<String, String>) {
    let lib = strip(&std::fs::read_to_string(src.join("lib.rs")).unwrap());
    let mut modules = BTreeSet::new();
    let mut reexports = BTreeMap::new();
    for line in lib.lines().map(str::trim) {
        let line = line.strip_prefix("pub ").unwrap_or(line);
        if let Some(rest) = line.strip_prefix("mod ") {
            modules.insert(ident(rest).to_string());
        } else if let Some(rest) = line.strip_prefix("use ") {
            let from = ident(rest).to_string();
            let after = &rest.trim_start()[from.len()..];
            let after = after.trim_start().trim_start_matches("::");
            let names = if after.trim_start().starts_with('{') {
                group_heads(after)
            } else {
                let last = after
                    .trim_end_matches(';')
                    .rsplit("::")
                    .next()
                    .unwrap_or("");
                vec![ident(last).to_string()]
            };
            for name in names {
                reexports.insert(name, from.clone());
            }
        }
    }
    (modules, reexports)
}

/// Every `.rs` file under `dir`.
fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The module path of a file: `a.rs` and `a/mod.rs` are `[a]`, `a/b.rs` is `[a, b]`.
fn module_path(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut path: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if path.last().is_some_and(|l| l == "mod") {
        path.pop();
    }
    path
}

/// The references of one file: `(referenced module, line)`.
fn references(
    text: &str,
    path: &[String],
    modules: &BTreeSet<String>,
    reexports: &BTreeMap<String, String>,
) -> Vec<(String, usize)> {
    let code = strip(text);
    let mut out = Vec::new();
    let resolve = |head: &str| -> Option<String> {
        if modules.contains(head) {
            Some(head.to_string())
        } else {
            reexports.get(head).cloned()
        }
    };
    // Inline modules (`mod tests { … }`) deepen the path `super` climbs from.
    let mut inline: Vec<usize> = Vec::new();
    let mut depth = 0usize;
    let mut line = 1;
    let b = code.as_bytes();
    let mut i = 0;
    while i < b.len() {
        let rest = &code[i..];
        let boundary = i == 0 || {
            let prev = code[..i].chars().next_back().unwrap();
            !is_ident(prev) && prev != '$'
        };
        match b[i] {
            b'\n' => line += 1,
            b'{' => depth += 1,
            b'}' => {
                depth = depth.saturating_sub(1);
                if inline.last() == Some(&depth) {
                    inline.pop();
                }
            }
            _ => {}
        }
        if boundary && rest.starts_with("mod ") {
            let name = ident(&rest[4..]);
            let after = rest[4..].trim_start()[name.len()..].trim_start();
            if after.starts_with('{') {
                inline.push(depth);
            }
        }
        if boundary && rest.starts_with("crate::") {
            let after = &rest["crate::".len()..];
            let heads = if after.trim_start().starts_with('{') {
                group_heads(after)
            } else {
                vec![ident(after).to_string()]
            };
            for head in heads {
                if let Some(m) = resolve(&head) {
                    out.push((m, line));
                }
            }
        }
        if boundary && rest.starts_with("super::") {
            // Count the `super::` segments, then see where they land.
            let mut climbs = 0;
            let mut tail = rest;
            while let Some(t) = tail.strip_prefix("super::") {
                climbs += 1;
                tail = t.trim_start();
            }
            let here = path.len() + inline.len();
            if climbs >= here {
                // At (or past) the crate root: the next segment names a module.
                if let Some(m) = resolve(ident(tail)) {
                    out.push((m, line));
                }
            }
            i += rest.len() - tail.len();
            continue;
        }
        i += rest.chars().next().map_or(1, char::len_utf8);
    }
    out
}

type Graph = BTreeMap<String, BTreeMap<String, Site>>;

fn graph() -> Graph {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let (modules, reexports) = root(&src);
    let mut all = Vec::new();
    files(&src, &mut all);
    all.sort();
    let mut graph: Graph = modules
        .iter()
        .map(|m| (m.clone(), BTreeMap::new()))
        .collect();
    for file in all {
        let path = module_path(&src, &file);
        if path == ["lib"] {
            continue;
        }
        let from = path[0].clone();
        let text = std::fs::read_to_string(&file).unwrap();
        for (to, line) in references(&text, &path, &modules, &reexports) {
            if to != from {
                let site = Site {
                    file: file.strip_prefix(&src).unwrap().to_path_buf(),
                    line,
                };
                graph
                    .entry(from.clone())
                    .or_default()
                    .entry(to)
                    .or_insert(site);
            }
        }
    }
    graph
}

/// A cycle of `graph`, if it has one, as the modules along it (first repeated last).
fn cycle(graph: &Graph) -> Option<Vec<String>> {
    #[derive(Clone, Copy, PartialEq)]
    enum Mark {
        Open,
        Done,
    }
    fn visit(
        node: &str,
        graph: &Graph,
        marks: &mut BTreeMap<String, Mark>,
        stack: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        marks.insert(node.to_string(), Mark::Open);
        stack.push(node.to_string());
        for next in graph.get(node).into_iter().flat_map(|e| e.keys()) {
            match marks.get(next) {
                Some(Mark::Open) => {
                    let start = stack.iter().position(|s| s == next).unwrap();
                    let mut cycle = stack[start..].to_vec();
                    cycle.push(next.clone());
                    return Some(cycle);
                }
                Some(Mark::Done) => {}
                None => {
                    if let Some(c) = visit(next, graph, marks, stack) {
                        return Some(c);
                    }
                }
            }
        }
        stack.pop();
        marks.insert(node.to_string(), Mark::Done);
        None
    }
    let mut marks = BTreeMap::new();
    for node in graph.keys() {
        if !marks.contains_key(node) {
            if let Some(c) = visit(node, graph, &mut marks, &mut Vec::new()) {
                return Some(c);
            }
        }
    }
    None
}

#[test]
fn top_level_modules_form_a_dag() {
    let graph = graph();
    if let Some(cycle) = cycle(&graph) {
        let mut message = format!("module cycle: {}\n", cycle.join(" -> "));
        for pair in cycle.windows(2) {
            let site = &graph[&pair[0]][&pair[1]];
            message += &format!(
                "  {} -> {}: src/{}:{}\n",
                pair[0],
                pair[1],
                site.file.display(),
                site.line
            );
        }
        message += "every reference:\n";
        for (from, edges) in &graph {
            for (to, site) in edges {
                message += &format!(
                    "  {from} -> {to}: src/{}:{}\n",
                    site.file.display(),
                    site.line
                );
            }
        }
        panic!("{message}");
    }
}

/// The scanner itself: what counts and what does not.
#[test]
fn the_rule_counts_code_and_docs_but_not_comments_or_strings() {
    let modules: BTreeSet<String> = ["a", "b", "c", "d", "e", "error"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let reexports: BTreeMap<String, String> = [("Error".to_string(), "error".to_string())]
        .into_iter()
        .collect();
    let text = r##"
//! See [`crate::b`].
use crate::{c::X, Error};
// crate::d is only mentioned in a comment
/* crate::d neither */
const S: &str = "crate::d";
const R: &str = r#"crate::d"#;
const Q: char = '"';
fn f<'a>(x: &'a str) -> &'a str { super::e::g(x) }
mod tests {
    use super::*;
}
"##;
    let path = vec!["a".to_string()];
    let found: BTreeSet<String> = references(text, &path, &modules, &reexports)
        .into_iter()
        .map(|(m, _)| m)
        .collect();
    let expected: BTreeSet<String> = ["b", "c", "e", "error"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    assert_eq!(found, expected);
    // Every module declared by lib.rs is a node, and the real graph has edges.
    let graph = graph();
    assert!(graph.contains_key("storage") && graph.contains_key("engine"));
    assert!(graph["engine"].contains_key("storage"));
}
