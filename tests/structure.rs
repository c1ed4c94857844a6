//! The shape of the source tree (issue 22): no import circle between the library's files, no
//! source file over 700 lines, no non-test function over 120 lines, at most 30 `pub mod`, and
//! no command-line flag (`--tools`) in a string literal below `workflow/` (the core names
//! settings in backticks, `` `tools` ``, and each front end spells them).
//!
//! The checks read `src/**/*.rs` as text: comments, string and character literals and
//! `#[cfg(test)]` items are blanked first, then `use` trees and `crate::`/`super::`/`self::`
//! paths are resolved to the file that defines their module (through a `mod.rs`'s re-exports to
//! the file an item comes from). A re-export (`pub use`) is a table of contents, not a
//! dependency of the file that holds it, so it is not an edge: whoever uses the name depends on
//! the file that defines it. `src/bin/` is its own crate and is left out
//! of the import check.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

const MAX_FILE_LINES: usize = 700;
const MAX_FUNCTION_LINES: usize = 120;
const MAX_PUB_MODS: usize = 30;

/// The folders whose string literals may spell command-line flags: the front end (`bin/`),
/// the workflows that map settings to it, and the reports that name the flag to give.
const FLAG_FOLDERS: &[&str] = &["bin/", "workflow/", "report/"];

/// Files that other work edits while this check lands (issue 22's next round splits them):
/// they may exceed the limits for now. Each entry is a path under `src/`.
const KNOWN_LONG: &[&str] = &[];

/// Long files and functions not split yet (the list only shrinks).
const NOT_YET_SPLIT: &[&str] = &[];

/// Import circles not broken yet, by their files (the list only shrinks).
const NOT_YET_UNTANGLED: &[&str] = &[];

/// Files that other work edits while this check lands, whose import circles the next round
/// breaks: a circle is excused only when every file of it is listed here.
const KNOWN_TANGLED: &[&str] = &[];

// ---------------------------------------------------------------------------------------------
// Lexing: code with comments, literals and test items blanked (newlines kept, so line numbers
// stay true).

/// `text` with comments and the contents of string and character literals replaced by spaces.
fn strip_comments_and_literals(text: &str) -> String {
    let chars: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let blank = |c: char| if c == '\n' { '\n' } else { ' ' };
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let next = chars.get(i + 1).copied();
        if c == '/' && next == Some('/') {
            while i < chars.len() && chars[i] != '\n' {
                out.push(' ');
                i += 1;
            }
        } else if c == '/' && next == Some('*') {
            let mut depth = 0;
            while i < chars.len() {
                if chars[i] == '/' && chars.get(i + 1) == Some(&'*') {
                    depth += 1;
                    out.push_str("  ");
                    i += 2;
                } else if chars[i] == '*' && chars.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    out.push_str("  ");
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    out.push(blank(chars[i]));
                    i += 1;
                }
            }
        } else if c == 'r'
            && (next == Some('"') || next == Some('#'))
            && !chars[..i]
                .last()
                .is_some_and(|p| p.is_alphanumeric() || *p == '_')
        {
            // A raw string r"…" or r#"…"#.
            let mut j = i + 1;
            let mut hashes = 0;
            while chars.get(j) == Some(&'#') {
                hashes += 1;
                j += 1;
            }
            if chars.get(j) != Some(&'"') {
                out.push(c);
                i += 1;
                continue;
            }
            out.push('"');
            for _ in i + 1..=j {
                out.push(' ');
            }
            i = j + 1;
            while i < chars.len() {
                if chars[i] == '"' && (0..hashes).all(|k| chars.get(i + 1 + k) == Some(&'#')) {
                    out.push('"');
                    for _ in 0..hashes {
                        out.push(' ');
                    }
                    i += 1 + hashes;
                    break;
                }
                out.push(blank(chars[i]));
                i += 1;
            }
        } else if c == '"' {
            out.push('"');
            i += 1;
            while i < chars.len() && chars[i] != '"' {
                if chars[i] == '\\' {
                    out.push(' ');
                    i += 1;
                }
                if i < chars.len() {
                    out.push(blank(chars[i]));
                    i += 1;
                }
            }
            out.push('"');
            i += 1;
        } else if c == '\'' {
            // A character literal ('x', '\n', '\u{..}') or a lifetime ('a): a literal closes
            // within a few characters.
            let close = if next == Some('\\') {
                (i + 2..chars.len().min(i + 12)).find(|&k| chars[k] == '\'')
            } else if chars.get(i + 2) == Some(&'\'') {
                Some(i + 2)
            } else {
                None
            };
            match close {
                Some(end) => {
                    out.push('\'');
                    for _ in i + 1..end {
                        out.push(' ');
                    }
                    out.push('\'');
                    i = end + 1;
                }
                None => {
                    out.push(c);
                    i += 1;
                }
            }
        } else {
            out.push(c);
            i += 1;
        }
    }
    out
}

/// The index of the brace matching the `{` at `open` in stripped code.
fn matching_brace(code: &[u8], open: usize) -> usize {
    let mut depth = 0usize;
    for (k, &b) in code.iter().enumerate().skip(open) {
        match b {
            b'{' => depth += 1,
            b'}' => {
                depth -= 1;
                if depth == 0 {
                    return k;
                }
            }
            _ => {}
        }
    }
    code.len().saturating_sub(1)
}

/// The end (inclusive) of the item starting at `start`: its `;` or its body's closing brace.
fn item_end(code: &[u8], start: usize) -> usize {
    let mut depth = 0i32;
    for k in start..code.len() {
        match code[k] {
            b'(' | b'[' => depth += 1,
            b')' | b']' => depth -= 1,
            b';' if depth == 0 => return k,
            b'{' if depth == 0 => return matching_brace(code, k),
            _ => {}
        }
    }
    code.len().saturating_sub(1)
}

/// Stripped code with every `#[cfg(test)]` item and `#[test]` function blanked.
fn without_tests(text: &str) -> String {
    let mut code = strip_comments_and_literals(text).into_bytes();
    for marker in ["#[cfg(test)]", "#[test]"] {
        let mut from = 0;
        while let Some(at) = find(&code, marker.as_bytes(), from) {
            let end = item_end(&code, at + marker.len());
            for b in &mut code[at..=end] {
                if *b != b'\n' {
                    *b = b' ';
                }
            }
            from = end + 1;
        }
    }
    String::from_utf8(code).expect("blanking keeps ASCII boundaries")
}

fn find(haystack: &[u8], needle: &[u8], from: usize) -> Option<usize> {
    (from..haystack.len().saturating_sub(needle.len() - 1))
        .find(|&k| &haystack[k..k + needle.len()] == needle)
}

fn is_ident(b: u8) -> bool {
    b.is_ascii_alphanumeric() || b == b'_'
}

fn line_of(code: &[u8], at: usize) -> usize {
    code[..at].iter().filter(|&&b| b == b'\n').count() + 1
}

// ---------------------------------------------------------------------------------------------
// Modules, uses and the import graph.

/// A source file: its path under `src/` (e.g. `calibration/plan.rs`) and its text.
struct Source {
    path: String,
    code: String,
}

/// The module path of a file under `src/`: `calibration/plan.rs` → `[calibration, plan]`.
fn module_of(path: &str) -> Vec<String> {
    let mut parts: Vec<String> = path.split('/').map(str::to_owned).collect();
    let last = parts.pop().unwrap_or_default();
    let stem = last.trim_end_matches(".rs");
    if stem != "mod" && stem != "lib" {
        parts.push(stem.to_owned());
    }
    parts
}

/// One `use` path or qualified path in a file.
struct Use {
    segments: Vec<String>,
    reexport: bool,
}

/// The leaf paths of a `use` tree: `a::{b, c::{d, self}}` → `a::b`, `a::c::d`, `a::c`.
fn expand_use_tree(tree: &str) -> Vec<Vec<String>> {
    let tree: String = tree.chars().filter(|c| !c.is_whitespace()).collect();
    let mut out = Vec::new();
    expand_into(&tree, &mut Vec::new(), &mut out);
    out
}

fn expand_into(tree: &str, prefix: &mut Vec<String>, out: &mut Vec<Vec<String>>) {
    let (head, group) = match tree.find('{') {
        Some(open) => (
            &tree[..open],
            Some(&tree[open + 1..tree.rfind('}').unwrap_or(tree.len())]),
        ),
        None => (tree, None),
    };
    let depth = prefix.len();
    for segment in head.split("::").filter(|s| !s.is_empty()) {
        prefix.push(segment.to_owned());
    }
    match group {
        None => {
            if prefix.last().is_some_and(|s| s == "self") {
                prefix.pop();
            }
            out.push(prefix.clone());
        }
        Some(group) => {
            let mut level = 0;
            let mut start = 0;
            let bytes = group.as_bytes();
            for k in 0..=bytes.len() {
                let at_end = k == bytes.len();
                if !at_end && bytes[k] == b'{' {
                    level += 1;
                } else if !at_end && bytes[k] == b'}' {
                    level -= 1;
                } else if at_end || (bytes[k] == b',' && level == 0) {
                    let part = &group[start..k];
                    if !part.is_empty() {
                        expand_into(part, prefix, out);
                    }
                    start = k + 1;
                }
            }
        }
    }
    prefix.truncate(depth);
}

/// The `use` paths and qualified `crate::`/`super::`/`self::` paths of stripped code.
fn uses_of(code: &str) -> Vec<Use> {
    let bytes = code.as_bytes();
    let mut uses = Vec::new();
    let mut in_use = vec![false; bytes.len()];
    let mut from = 0;
    while let Some(at) = find(bytes, b"use ", from) {
        from = at + 4;
        if at > 0 && is_ident(bytes[at - 1]) {
            continue;
        }
        let Some(end) = find(bytes, b";", at) else {
            break;
        };
        let before = code[..at].trim_end();
        let line_start = before.rfind('\n').map_or(0, |k| k + 1);
        let reexport = before[line_start..].trim_start().starts_with("pub");
        let tree = code[at + 4..end].replace(" as ", "@");
        for mut segments in expand_use_tree(&tree) {
            if let Some(last) = segments.last_mut() {
                if let Some(cut) = last.find('@') {
                    last.truncate(cut);
                }
            }
            uses.push(Use { segments, reexport });
        }
        in_use[at..=end].iter_mut().for_each(|b| *b = true);
    }
    // Qualified paths in code outside `use` statements (`crate::a::b`, `super::x`, `plan::f`:
    // the resolver keeps those that start at a module).
    let mut at = 0;
    while at < bytes.len() {
        let starts = is_ident(bytes[at])
            && !bytes[at].is_ascii_digit()
            && (at == 0 || !(is_ident(bytes[at - 1]) || bytes[at - 1] == b':'));
        if !starts || in_use[at] {
            at += 1;
            continue;
        }
        let mut end = at;
        while end < bytes.len() && (is_ident(bytes[end]) || bytes[end] == b':') {
            end += 1;
        }
        let segments: Vec<String> = code[at..end]
            .split("::")
            .filter(|s| !s.is_empty())
            .map(str::to_owned)
            .collect();
        if segments.len() > 1 {
            uses.push(Use {
                segments,
                reexport: false,
            });
        }
        at = end;
    }
    uses
}

/// The import graph of a crate's files: the files each file imports from.
struct Graph {
    files: Vec<String>,
    edges: BTreeMap<String, BTreeSet<String>>,
}

fn import_graph(sources: &[Source]) -> Graph {
    let by_module: BTreeMap<Vec<String>, &Source> =
        sources.iter().map(|s| (module_of(&s.path), s)).collect();
    let uses: BTreeMap<&str, Vec<Use>> = sources
        .iter()
        .map(|s| (s.path.as_str(), uses_of(&s.code)))
        .collect();
    let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for source in sources {
        let here = module_of(&source.path);
        for u in &uses[source.path.as_str()] {
            if u.reexport {
                continue;
            }
            if let Some(target) = resolve(&here, &u.segments, &by_module, &uses, 0) {
                if target != source.path {
                    edges.entry(source.path.clone()).or_default().insert(target);
                }
            }
        }
    }
    Graph {
        files: sources.iter().map(|s| s.path.clone()).collect(),
        edges,
    }
}

/// The file a path used in module `here` points into, through `mod.rs` re-exports.
fn resolve(
    here: &[String],
    segments: &[String],
    by_module: &BTreeMap<Vec<String>, &Source>,
    uses: &BTreeMap<&str, Vec<Use>>,
    depth: usize,
) -> Option<String> {
    let mut module: Vec<String> = match segments.first().map(String::as_str) {
        Some("crate") => Vec::new(),
        Some("super") | Some("self") => here.to_vec(),
        // A child module named without `self::` (`mod plan;` … `plan::calibrate`).
        Some(child) if by_module.contains_key(&[here, &[child.to_owned()]].concat()) => {
            here.to_vec()
        }
        _ => return None,
    };
    let child = !matches!(segments[0].as_str(), "crate" | "super" | "self");
    let mut rest = if child { segments } else { &segments[1..] };
    if segments[0] == "super" {
        module.pop();
    }
    while rest.first().is_some_and(|s| s == "super") {
        module.pop();
        rest = &rest[1..];
    }
    while let Some(next) = rest.first() {
        let mut deeper = module.clone();
        deeper.push(next.clone());
        if !by_module.contains_key(&deeper) {
            break;
        }
        module = deeper;
        rest = &rest[1..];
    }
    let file = by_module.get(&module)?;
    if let (Some(item), true) = (rest.first(), depth < 8) {
        // Follow a re-export of the item to the file that defines it.
        for u in &uses[file.path.as_str()] {
            if u.reexport && u.segments.last() == Some(item) {
                let mut target = u.segments.clone();
                if !matches!(target[0].as_str(), "crate" | "super" | "self") {
                    target.insert(0, "self".to_owned());
                }
                target.extend(rest[1..].iter().cloned());
                return resolve(&module, &target, by_module, uses, depth + 1)
                    .or_else(|| Some(file.path.clone()));
            }
        }
    }
    Some(file.path.clone())
}

/// Every import circle: the groups of two or more files that reach each other (strongly
/// connected), each as its files and one loop through its first file (`a.rs → b.rs → a.rs`).
fn circles(graph: &Graph) -> Vec<(Vec<String>, String)> {
    let index: BTreeMap<&str, usize> = graph
        .files
        .iter()
        .enumerate()
        .map(|(k, f)| (f.as_str(), k))
        .collect();
    let next: Vec<Vec<usize>> = graph
        .files
        .iter()
        .map(|f| {
            graph.edges.get(f).map_or_else(Vec::new, |to| {
                to.iter()
                    .filter_map(|t| index.get(t.as_str()).copied())
                    .collect()
            })
        })
        .collect();
    // Breadth-first parents from each file: `parents[a][b]` is b's predecessor on a shortest
    // path from a (`Some(a)` for a's own successors), `None` where a does not reach b.
    let parents: Vec<Vec<Option<usize>>> = (0..next.len())
        .map(|from| {
            let mut parent = vec![None; next.len()];
            let mut queue = std::collections::VecDeque::from([from]);
            while let Some(n) = queue.pop_front() {
                for &m in &next[n] {
                    if parent[m].is_none() {
                        parent[m] = Some(n);
                        queue.push_back(m);
                    }
                }
            }
            parent
        })
        .collect();
    let mut grouped = vec![false; next.len()];
    let mut found = Vec::new();
    for start in 0..next.len() {
        if grouped[start] || parents[start][start].is_none() {
            continue;
        }
        let group: Vec<usize> = (0..next.len())
            .filter(|&n| parents[start][n].is_some() && parents[n][start].is_some())
            .collect();
        let mut back = Vec::new();
        let mut n = parents[start][start].expect("start reaches itself");
        while n != start {
            back.push(n);
            n = parents[start][n].expect("on a path from start");
        }
        let path: Vec<usize> = [start]
            .into_iter()
            .chain(back.into_iter().rev())
            .chain([start])
            .collect();
        group.iter().for_each(|&n| grouped[n] = true);
        let files = group.iter().map(|&n| graph.files[n].clone()).collect();
        let loop_text: Vec<&str> = path.iter().map(|&n| graph.files[n].as_str()).collect();
        found.push((files, loop_text.join(" → ")));
    }
    found
}

// ---------------------------------------------------------------------------------------------
// Lengths.

/// The non-test functions of a file longer than `limit` lines: (line, name, length).
fn long_functions(text: &str, limit: usize) -> Vec<(usize, String, usize)> {
    let code = without_tests(text);
    let bytes = code.as_bytes();
    let mut found = Vec::new();
    let mut from = 0;
    while let Some(at) = find(bytes, b"fn ", from) {
        from = at + 3;
        if at > 0 && is_ident(bytes[at - 1]) {
            continue;
        }
        let name: String = code[at + 3..]
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        if name.is_empty() {
            continue; // a `fn(` pointer type
        }
        let end = item_end(bytes, at + 3);
        if bytes[end] != b'}' {
            continue; // a trait method without a body
        }
        let length = line_of(bytes, end) - line_of(bytes, at) + 1;
        if length > limit {
            found.push((line_of(bytes, at), name, length));
        }
    }
    found
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .expect("src/ is readable")
        .map(|e| e.expect("a directory entry").path())
        .collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Every `.rs` file under `src/`, as (path under `src/`, text).
fn sources() -> Vec<(String, String)> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    files
        .into_iter()
        .map(|p| {
            let relative = p.strip_prefix(&src).expect("under src/");
            let text = std::fs::read_to_string(&p).expect("a source file is UTF-8");
            (relative.to_string_lossy().replace('\\', "/"), text)
        })
        .collect()
}

fn library_sources() -> Vec<Source> {
    sources()
        .into_iter()
        .filter(|(path, _)| !path.starts_with("bin/"))
        .map(|(path, text)| Source {
            path,
            code: without_tests(&text),
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Public modules and flags in literals.

/// How many `pub mod` items stripped code declares (`pub(crate) mod` is not public).
fn pub_mods(code: &str) -> usize {
    let bytes = code.as_bytes();
    let mut count = 0;
    let mut from = 0;
    while let Some(at) = find(bytes, b"pub mod ", from) {
        from = at + 8;
        if at == 0 || !is_ident(bytes[at - 1]) {
            count += 1;
        }
    }
    count
}

/// The string literals of `text` outside comments and test items: (line, contents as
/// written, escapes included).
fn literals_outside_tests(text: &str) -> Vec<(usize, String)> {
    // The stripped text keeps one character per character of `text`, a literal as its two
    // quotes around blanks; `without_tests` blanks the test items of it byte for byte.
    let stripped = strip_comments_and_literals(text);
    let kept = without_tests(text);
    let original: Vec<char> = text.chars().collect();
    let mut found = Vec::new();
    let mut open: Option<(usize, usize)> = None;
    for (k, (at, c)) in stripped.char_indices().enumerate() {
        if c != '"' {
            continue;
        }
        match open.take() {
            None => open = Some((k, at)),
            Some((start, start_at)) => {
                if kept.as_bytes()[start_at] == b'"' {
                    let contents = original[start + 1..k.min(original.len())].iter().collect();
                    found.push((line_of(stripped.as_bytes(), start_at), contents));
                }
            }
        }
    }
    found
}

/// The command-line flags (`--tools`, `--length-unit`) a literal spells: two dashes, not
/// after a word or a third dash, then a lower-case letter.
fn flags_in(literal: &str) -> Vec<String> {
    let bytes = literal.as_bytes();
    let mut flags = Vec::new();
    let mut from = 0;
    while let Some(at) = find(bytes, b"--", from) {
        from = at + 2;
        let after_word = at > 0 && (is_ident(bytes[at - 1]) || bytes[at - 1] == b'-');
        if after_word || !bytes.get(at + 2).is_some_and(u8::is_ascii_lowercase) {
            continue;
        }
        let end = (at + 2..bytes.len())
            .find(|&k| !(bytes[k].is_ascii_alphanumeric() || bytes[k] == b'-'))
            .unwrap_or(bytes.len());
        flags.push(literal[at..end].to_owned());
        from = end;
    }
    flags
}

/// The flags spelled in the non-test string literals of a file: (line, flag).
fn flag_literals(text: &str) -> Vec<(usize, String)> {
    literals_outside_tests(text)
        .into_iter()
        .flat_map(|(line, literal)| flags_in(&literal).into_iter().map(move |f| (line, f)))
        .collect()
}

// ---------------------------------------------------------------------------------------------
// The checks.

#[test]
fn no_import_circle_between_source_files() {
    let graph = import_graph(&library_sources());
    if let Ok(prefix) = std::env::var("TREECAL_IMPORTS_OF") {
        // A look at the graph while untangling: `TREECAL_IMPORTS_OF=calibration/ cargo test …`.
        for (from, to) in graph.edges.iter().filter(|(f, _)| f.starts_with(&prefix)) {
            eprintln!(
                "{from} → {}",
                to.iter().cloned().collect::<Vec<_>>().join(", ")
            );
        }
    }
    let found: Vec<String> = circles(&graph)
        .into_iter()
        .filter(|(files, _)| {
            !files.iter().all(|f| {
                KNOWN_TANGLED.contains(&f.as_str()) || NOT_YET_UNTANGLED.contains(&f.as_str())
            })
        })
        .map(|(files, loop_text)| format!("{loop_text} (all of {})", files.join(", ")))
        .collect();
    assert!(
        found.is_empty(),
        "import circles between files of src/ (move the shared pieces down into a file of \
         their own):\n{}",
        found.join("\n")
    );
}

#[test]
fn no_source_file_or_function_too_long() {
    let mut problems = Vec::new();
    for (path, text) in sources() {
        if KNOWN_LONG.contains(&path.as_str()) || NOT_YET_SPLIT.contains(&path.as_str()) {
            continue;
        }
        let lines = text.lines().count();
        if lines > MAX_FILE_LINES {
            problems.push(format!(
                "src/{path}: {lines} lines (at most {MAX_FILE_LINES})"
            ));
        }
        for (line, name, length) in long_functions(&text, MAX_FUNCTION_LINES) {
            problems.push(format!(
                "src/{path}:{line}: fn {name} is {length} lines (at most {MAX_FUNCTION_LINES})"
            ));
        }
    }
    assert!(
        problems.is_empty(),
        "split these along the steps their comments name:\n{}",
        problems.join("\n")
    );
}

#[test]
fn at_most_30_public_modules() {
    let mods: Vec<(String, usize)> = library_sources()
        .into_iter()
        .map(|s| (s.path, pub_mods(&s.code)))
        .filter(|(_, n)| *n > 0)
        .collect();
    let total: usize = mods.iter().map(|(_, n)| n).sum();
    assert!(
        total <= MAX_PUB_MODS,
        "{total} `pub mod` (at most {MAX_PUB_MODS}; make a module private and re-export its \
         items): {mods:?}"
    );
}

/// The core names a setting (`` `tools` ``), never the flag that sets it: Python users see its
/// messages too, and the command line and the Python binding each spell the setting their way
/// (`treecal::error::name_settings`).
#[test]
fn no_cli_flag_in_string_literals_below_workflow() {
    let mut problems = Vec::new();
    for (path, text) in sources() {
        if FLAG_FOLDERS.iter().any(|folder| path.starts_with(folder)) {
            continue;
        }
        for (line, flag) in flag_literals(&text) {
            problems.push(format!("src/{path}:{line}: {flag}"));
        }
    }
    assert!(
        problems.is_empty(),
        "flags in string literals below workflow/ (name the setting in backticks instead, \
         `tools` for --tools, or move the wording up into workflow/):\n{}",
        problems.join("\n")
    );
}

/// The checker itself can fail: a circle of three files around a re-export, a test module's
/// import that does not count, and a long function named.
#[test]
fn structure_checks_find_what_they_look_for() {
    let source = |path: &str, text: &str| Source {
        path: path.to_owned(),
        code: without_tests(text),
    };
    let crate_files = [
        source("lib.rs", "pub mod a;\npub mod b;\n"),
        source(
            "a/mod.rs",
            "mod inner;\npub use inner::Thing;\nuse crate::b::{self, Other as O};\n",
        ),
        source("a/inner.rs", "// use crate::b;\npub struct Thing;\nfn f() { let _ = \"crate::b::x\"; }\n"),
        source("b.rs", "use super::a::Thing;\npub struct Other;\n#[cfg(test)]\nmod tests { use crate::a::inner; }\n"),
    ];
    let graph = import_graph(&crate_files);
    assert_eq!(
        graph
            .edges
            .get("b.rs")
            .map(|e| e.iter().cloned().collect::<Vec<_>>()),
        Some(vec!["a/inner.rs".to_owned()]),
        "b.rs's import of a::Thing resolves through the re-export to a/inner.rs"
    );
    assert!(circles(&graph).is_empty());

    let circle = [
        source("lib.rs", "mod a;\nmod b;\nmod c;\n"),
        source("a.rs", "use crate::b::B;\npub struct A;\n"),
        source("b.rs", "pub struct B;\nfn f() -> crate::c::C { todo!() }\n"),
        source("c.rs", "use crate::{a::A, b};\npub struct C;\n"),
    ];
    let found = circles(&import_graph(&circle));
    assert_eq!(found.len(), 1);
    assert_eq!(found[0].1, "a.rs → b.rs → c.rs → a.rs");

    let parent_and_child = [
        source("lib.rs", "mod a;\n"),
        source("a/mod.rs", "mod inner;\npub fn f() -> u8 { inner::g() }\n"),
        source("a/inner.rs", "pub fn g() -> u8 { super::f() }\n"),
    ];
    let found = circles(&import_graph(&parent_and_child));
    assert_eq!(found.len(), 1);
    assert_eq!(found[0].1, "a/mod.rs → a/inner.rs → a/mod.rs");

    let long = format!(
        "fn short() {{}}\nfn long(x: [f64; 3]) -> f64 {{\n{}    x[0]\n}}\n#[cfg(test)]\nmod tests {{\n    fn long_test() {{\n{}    }}\n}}\n",
        "    let _ = '{';\n".repeat(130),
        "\n".repeat(130)
    );
    assert_eq!(
        long_functions(&long, MAX_FUNCTION_LINES),
        vec![(2, "long".to_owned(), 133)]
    );

    let modules = "pub mod a;\npub(crate) mod b;\n// pub mod c;\nmod d { pub mod e {} }\n#[cfg(test)]\npub mod f;\n";
    assert_eq!(pub_mods(&without_tests(modules)), 2);
}

/// The flag check can fail: a flag in a literal is found with its line, one in a comment, a
/// test, a table rule (`| --- |`) or a word (`a--b`) is not.
#[test]
fn flag_check_finds_flags_in_literals_only() {
    let text = r##"
/// Give --tools to name them.
fn f() -> String {
    // --not-this
    let table = "| --- | ---: |";
    let dashes = "a--b, x --9";
    format!("name a link beyond it (--tools) or set {}", r#"--length-unit mm"#)
}
#[cfg(test)]
mod tests {
    fn g() -> &'static str { "--in-a-test" }
}
"##;
    assert_eq!(
        flag_literals(text),
        vec![(7, "--tools".to_owned()), (7, "--length-unit".to_owned())]
    );
    assert_eq!(flags_in("give `tools` (a setting)"), Vec::<String>::new());
}
