//! Repository hygiene: the invariants ARCHITECTURE.md states, checked by reading the sources.
//! Every Rust file starts with a `//!` doc; the layers import only downwards and the lower ones
//! know neither tokio nor MAVLink; the library never prints; no test is ignored; no two files in
//! src/ import each other, directly or round a longer circle; every path, `.md` file and module
//! path a document or a `//!` doc names exists. Each failure names the file and line.
//!
//! The sources are read as text with comments and string literals blanked out, so a word in a
//! comment or a message is never taken for code. Code under `#[cfg(test)]` is test code: it may
//! print and may reach any layer (a link test checks its read-back against the mock's storage),
//! but it may not bring tokio or MAVLink into a lower layer either.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Component, Path, PathBuf};

/// The library's layers, lowest first: a module may import only modules of a lower layer
/// (ARCHITECTURE.md, "Layers"). Modules of one layer know nothing of each other, so `tour`
/// never imports `physics`. A new module gets its layer here.
const LAYERS: &[(&str, u32)] = &[
    ("rng", 0),
    ("names", 0),
    ("mission", 0),
    ("physics", 1),
    ("tour", 1),
    ("flightlog", 1),
    ("planner", 2),
    ("output", 2),
    ("logfit", 3),
    ("link", 3),
    ("sim", 4),
    ("ledger", 4),
    ("plot", 4),
    ("session", 5),
    ("service", 6),
];

/// The modules that use neither tokio nor the mavlink crate, test code included.
const NO_TOKIO_NO_MAVLINK: &[&str] = &[
    "rng",
    "mission",
    "physics",
    "tour",
    "flightlog",
    "planner",
    "output",
    "logfit",
];

/// Where a document's path may point: the repository's own top-level entries.
const REPO_DIRS: &[&str] = &[
    "src/",
    "docs/",
    "sitl/",
    "models/",
    "missions/",
    "tests/",
    "benches/",
    ".ci/",
];

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// One Rust source file: its path from the repository root ('/'-separated), its text, its
/// lines with comments and literals blanked, and which of those lines are test code.
struct Source {
    rel: String,
    text: String,
    code: Vec<String>,
    test: Vec<bool>,
}

impl Source {
    fn read(rel: String) -> Source {
        let text = std::fs::read_to_string(root().join(&rel))
            .unwrap_or_else(|e| panic!("{rel}: cannot read: {e}"));
        let code: Vec<String> = blank(&text).lines().map(str::to_string).collect();
        let test = test_lines(&code);
        Source {
            rel,
            text,
            code,
            test,
        }
    }

    /// The code lines (1-based number, blanked text) that are not test code.
    fn non_test(&self) -> impl Iterator<Item = (usize, &str)> {
        self.code
            .iter()
            .enumerate()
            .filter(|(k, _)| !self.test[*k])
            .map(|(k, l)| (k + 1, l.as_str()))
    }

    /// The library module it belongs to (`tour` for src/tour/held_karp.rs), or None for the
    /// crate roots, the binary (src/main.rs, src/cmd/) and files outside src/.
    fn layer_module(&self) -> Option<&str> {
        let rest = self.rel.strip_prefix("src/")?;
        let first = rest.split('/').next()?;
        let name = first.strip_suffix(".rs").unwrap_or(first);
        (!matches!(name, "lib" | "main" | "cmd")).then_some(name)
    }

    /// Its module path below its crate root: src/tour/sorties/mod.rs is [tour, sorties].
    fn module_path(&self) -> Vec<String> {
        let Some(rest) = self.rel.strip_prefix("src/") else {
            return Vec::new();
        };
        let rest = rest.strip_suffix(".rs").unwrap_or(rest);
        let mut segments: Vec<String> = rest.split('/').map(str::to_string).collect();
        if matches!(
            segments.last().map(String::as_str),
            Some("mod" | "lib" | "main")
        ) {
            segments.pop();
        }
        segments
    }
}

fn walk(dir: &Path, keep: &dyn Fn(&Path) -> bool, out: &mut Vec<String>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries {
        let path = entry.expect("directory entry").path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if path.is_dir() {
            if !matches!(name, "target" | ".git" | "node_modules") {
                walk(&path, keep, out);
            }
        } else if keep(&path) {
            let rel = path.strip_prefix(root()).expect("inside the repository");
            out.push(rel.to_string_lossy().replace('\\', "/"));
        }
    }
}

/// Every Rust file of src/, tests/ and benches/, sorted.
fn sources() -> Vec<Source> {
    let mut files = Vec::new();
    for dir in ["src", "tests", "benches"] {
        walk(
            &root().join(dir),
            &|p| p.extension().is_some_and(|e| e == "rs"),
            &mut files,
        );
    }
    files.sort();
    assert!(files.len() > 5, "found only {} Rust files", files.len());
    let mut sources: Vec<Source> = files.into_iter().map(Source::read).collect();
    mark_test_only_files(&mut sources);
    sources
}

/// The text with every comment and the inside of every string and character literal replaced by
/// spaces; line breaks are kept, so line numbers stay.
fn blank(text: &str) -> String {
    let chars: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    let keep = |c: char| if c == '\n' { '\n' } else { ' ' };
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
                    out.push(keep(chars[i]));
                    i += 1;
                }
            }
        } else if c == 'r'
            && (next == Some('"') || next == Some('#'))
            && !(i > 0 && (chars[i - 1].is_alphanumeric() || chars[i - 1] == '_'))
        {
            // A raw string r"..." or r#"..."#, or an identifier like r#type.
            let mut j = i + 1;
            while chars.get(j) == Some(&'#') {
                j += 1;
            }
            if chars.get(j) != Some(&'"') {
                out.push(c);
                i += 1;
                continue;
            }
            let hashes = j - i - 1;
            out.extend(std::iter::repeat_n(' ', j + 1 - i));
            i = j + 1;
            while i < chars.len() {
                if chars[i] == '"' && (1..=hashes).all(|h| chars.get(i + h) == Some(&'#')) {
                    out.extend(std::iter::repeat_n(' ', hashes + 1));
                    i += hashes + 1;
                    break;
                }
                out.push(keep(chars[i]));
                i += 1;
            }
        } else if c == '"' {
            out.push(' ');
            i += 1;
            while i < chars.len() && chars[i] != '"' {
                if chars[i] == '\\' {
                    out.push(' ');
                    i += 1;
                }
                if i < chars.len() {
                    out.push(keep(chars[i]));
                    i += 1;
                }
            }
            out.push(' ');
            i += 1;
        } else if c == '\'' && next == Some('\\') {
            // '\n', '\'', '\u{..}'
            let mut j = i + 2;
            while j < chars.len() && chars[j] != '\'' && chars[j] != '\n' {
                j += 1;
            }
            out.extend(std::iter::repeat_n(' ', j + 1 - i));
            i = j + 1;
        } else if c == '\'' && chars.get(i + 2) == Some(&'\'') {
            out.push_str("   ");
            i += 3;
        } else {
            out.push(c);
            i += 1;
        }
    }
    out
}

/// Which blanked lines are test code: the item after each `#[cfg(test)]`, through its closing
/// brace or semicolon.
fn test_lines(code: &[String]) -> Vec<bool> {
    let mut test = vec![false; code.len()];
    let mut k = 0;
    while k < code.len() {
        if code[k].trim() != "#[cfg(test)]" {
            k += 1;
            continue;
        }
        let start = k;
        let mut depth = 0i32;
        let mut opened = false;
        let mut end = code.len() - 1;
        'item: for (j, line) in code.iter().enumerate().skip(k + 1) {
            for c in line.chars() {
                match c {
                    '{' => {
                        depth += 1;
                        opened = true;
                    }
                    '}' => depth -= 1,
                    ';' if !opened => {
                        end = j;
                        break 'item;
                    }
                    _ => {}
                }
                if opened && depth == 0 {
                    end = j;
                    break 'item;
                }
            }
        }
        for flag in &mut test[start..=end] {
            *flag = true;
        }
        k = end + 1;
    }
    test
}

/// Marks as test code the files that a `#[cfg(test)] mod name;` declares.
fn mark_test_only_files(sources: &mut [Source]) {
    let mut test_files = BTreeSet::new();
    for s in sources.iter() {
        let dir = match s.rel.rsplit_once('/') {
            Some((dir, "mod.rs" | "lib.rs" | "main.rs")) => dir.to_string(),
            _ => s.rel.trim_end_matches(".rs").to_string(),
        };
        for (k, line) in s.code.iter().enumerate() {
            let line = line.trim();
            let Some(name) = line
                .strip_suffix(';')
                .and_then(|l| l.rsplit_once("mod ").map(|(_, n)| n.trim()))
            else {
                continue;
            };
            if k > 0 && s.code[k - 1].trim() == "#[cfg(test)]" {
                test_files.insert(format!("{dir}/{name}.rs"));
                test_files.insert(format!("{dir}/{name}/mod.rs"));
            }
        }
    }
    for s in sources.iter_mut() {
        let in_tests = s.rel.starts_with("tests/") || s.rel.starts_with("benches/");
        if in_tests || test_files.contains(&s.rel) {
            s.test = vec![true; s.code.len()];
        }
    }
}

fn is_ident_char(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// The identifiers of a blanked line with their byte offsets.
fn identifiers(line: &str) -> Vec<(usize, &str)> {
    let mut out = Vec::new();
    let mut start = None;
    for (i, c) in line
        .char_indices()
        .chain(std::iter::once((line.len(), ' ')))
    {
        match (start, is_ident_char(c)) {
            (None, true) => start = Some(i),
            (Some(s), false) => {
                out.push((s, &line[s..i]));
                start = None;
            }
            _ => {}
        }
    }
    out
}

/// Every path below `crate::`, `super::`, `self::` or `emplan::` in a blanked line, with use
/// groups expanded: `use crate::link::{items, transfer::{self, X}}` gives [crate, link, items],
/// [crate, link, transfer] and [crate, link, transfer, X].
fn paths(code: &[String], line: usize) -> Vec<Vec<String>> {
    // A use group may run over several lines: read on until its braces close.
    let mut text = code[line].clone();
    if text.contains("::{") {
        for more in code.iter().skip(line + 1).take(60) {
            if text.matches('{').count() <= text.matches('}').count() {
                break;
            }
            text.push(' ');
            text.push_str(more);
        }
    }
    let first_len = code[line].len();
    let mut out = Vec::new();
    for (at, word) in identifiers(&text) {
        if at >= first_len {
            break;
        }
        let before = text[..at].chars().next_back();
        if !matches!(word, "crate" | "super" | "self" | "emplan")
            || before.is_some_and(|c| c == ':' || is_ident_char(c))
            || !text[at + word.len()..].starts_with("::")
        {
            continue;
        }
        let mut rest = &text[at..];
        parse_tree(&mut rest, Vec::new(), &mut out);
    }
    out
}

/// Parses `a::b::{c, d::e}` at the start of `rest`, pushing each leaf path onto `out`.
fn parse_tree(rest: &mut &str, prefix: Vec<String>, out: &mut Vec<Vec<String>>) {
    let mut path = prefix;
    loop {
        *rest = rest.trim_start();
        if let Some(group) = rest.strip_prefix('{') {
            *rest = group;
            loop {
                *rest = rest.trim_start();
                if let Some(after) = rest.strip_prefix('}') {
                    *rest = after;
                    return;
                }
                if let Some(after) = rest.strip_prefix(',') {
                    *rest = after;
                    continue;
                }
                let before = rest.len();
                parse_tree(rest, path.clone(), out);
                if rest.len() == before {
                    // Not a path (e.g. `*`): skip a character.
                    let mut chars = rest.chars();
                    chars.next();
                    *rest = chars.as_str();
                    if rest.is_empty() {
                        return;
                    }
                }
            }
        }
        let len = rest.find(|c: char| !is_ident_char(c)).unwrap_or(rest.len());
        if len == 0 {
            break;
        }
        let segment = &rest[..len];
        *rest = &rest[len..];
        if segment != "self" || path.is_empty() {
            path.push(segment.to_string());
        }
        match rest.strip_prefix("::") {
            Some(after) => *rest = after,
            None => break,
        }
    }
    if !path.is_empty() {
        out.push(path);
    }
}

/// The file of module `segments` below src/, if there is one.
fn module_file(segments: &[String]) -> Option<String> {
    if segments.is_empty() {
        return None;
    }
    let base = format!("src/{}", segments.join("/"));
    [format!("{base}.rs"), format!("{base}/mod.rs")]
        .into_iter()
        .find(|f| root().join(f).is_file())
}

/// The file a path names (the longest prefix of it that is a module with a file), or None when
/// it leaves the crate or names the crate root.
fn resolve(source: &Source, path: &[String]) -> Option<String> {
    let mut base = source.module_path();
    let mut segments = path;
    match segments.first().map(String::as_str) {
        Some("crate") if source.rel.starts_with("src/") => base.clear(),
        Some("emplan") => base.clear(),
        Some("super") => {
            while segments.first().map(String::as_str) == Some("super") {
                base.pop()?;
                segments = &segments[1..];
            }
            return longest_module(base, segments);
        }
        Some("self") => {}
        _ => return None,
    }
    longest_module(base, &segments[1..])
}

fn longest_module(mut base: Vec<String>, segments: &[String]) -> Option<String> {
    let mut found = module_file(&base);
    for segment in segments {
        base.push(segment.clone());
        match module_file(&base) {
            Some(file) => found = Some(file),
            None => break,
        }
    }
    found
}

fn layer_of(module: &str) -> Option<u32> {
    LAYERS.iter().find(|(m, _)| *m == module).map(|(_, l)| *l)
}

fn fail(check: &str, problems: &[String]) {
    assert!(problems.is_empty(), "{check}:\n  {}", problems.join("\n  "));
}

#[test]
fn every_source_file_starts_with_a_module_doc() {
    let missing: Vec<String> = sources()
        .iter()
        .filter(|s| !s.text.trim_start().starts_with("//!"))
        .map(|s| format!("{}:1: no leading //! doc", s.rel))
        .collect();
    fail("files without a leading //! doc", &missing);
}

#[test]
fn lower_layers_import_neither_higher_ones_nor_tokio_nor_mavlink() {
    let mut problems = Vec::new();
    for s in sources() {
        let Some(module) = s.layer_module() else {
            continue;
        };
        let Some(layer) = layer_of(module) else {
            problems.push(format!(
                "{}:1: module `{module}` has no layer in tests/it/tidy.rs's LAYERS",
                s.rel
            ));
            continue;
        };
        let pure = NO_TOKIO_NO_MAVLINK.contains(&module);
        for (k, line) in s.code.iter().enumerate() {
            let n = k + 1;
            for (at, word) in identifiers(line) {
                let before = line[..at].chars().next_back();
                let path_root = !before.is_some_and(|c| c == ':' || is_ident_char(c));
                if pure && path_root && matches!(word, "tokio" | "mavlink") {
                    problems.push(format!("{}:{n}: `{module}` uses {word}", s.rel));
                }
            }
            if s.test[k] {
                continue;
            }
            for path in paths(&s.code, k) {
                if path[0] != "crate" || path.len() < 2 {
                    continue;
                }
                let target = path[1].as_str();
                if target == module {
                    continue;
                }
                match layer_of(target) {
                    Some(l) if l < layer => {}
                    Some(l) => problems.push(format!(
                        "{}:{n}: `{module}` (layer {layer}) imports `{}` (layer {l}): a module \
                         imports only lower layers",
                        s.rel,
                        path.join("::")
                    )),
                    None => {}
                }
            }
        }
    }
    fail(
        "layering (tests/it/tidy.rs LAYERS, ARCHITECTURE.md)",
        &problems,
    );
}

#[test]
fn the_library_never_prints() {
    let mut problems = Vec::new();
    for s in sources() {
        let binary = s.rel == "src/main.rs" || s.rel.starts_with("src/cmd/");
        if !s.rel.starts_with("src/") || binary {
            continue;
        }
        for (n, line) in s.non_test() {
            for (at, word) in identifiers(line) {
                let is_macro = line[at + word.len()..].starts_with('!');
                if is_macro && matches!(word, "println" | "eprintln" | "print" | "eprint" | "dbg") {
                    problems.push(format!(
                        "{}:{n}: {word}! in the library (return it, or trace it)",
                        s.rel
                    ));
                }
            }
        }
    }
    fail("the library prints", &problems);
}

#[test]
fn no_test_is_ignored_or_expected_to_panic() {
    let mut problems = Vec::new();
    for s in sources() {
        for (k, line) in s.code.iter().enumerate() {
            let compact: String = line.chars().filter(|c| !c.is_whitespace()).collect();
            for banned in ["#[ignore", "#[should_panic"] {
                if compact.contains(banned) {
                    problems.push(format!("{}:{}: {banned}]", s.rel, k + 1));
                }
            }
        }
    }
    fail(
        "tests must run and assert what happens (a known-wrong behaviour is asserted as it is, with a FIXME)",
        &problems,
    );
}

#[test]
fn no_source_or_test_reads_the_shared_folder_beside_the_repository() {
    // A clone alone passes its tests: what a test needs is copied into tests/fixtures. The
    // needle is built so that this file does not name it.
    let needle = format!("../{}/", "shared");
    let mut problems = Vec::new();
    for s in sources() {
        for (k, line) in s.text.lines().enumerate() {
            if line.contains(&needle) && !line.trim_start().starts_with("//") {
                problems.push(format!("{}:{}: {}", s.rel, k + 1, line.trim()));
            }
        }
    }
    fail(
        "a clone without the shared folder beside it must pass its tests and benches",
        &problems,
    );
}

/// Whether `text` holds a calendar date (`YYYY-MM-DD`) that is not a timestamp's (a date
/// followed by a time of day is a value a test converts, not when something was written).
fn has_date(text: &str) -> bool {
    let b = text.as_bytes();
    (0..b.len().saturating_sub(9)).any(|i| {
        let digits = |r: std::ops::Range<usize>| r.clone().all(|k| b[k].is_ascii_digit());
        let before = i == 0 || !b[i - 1].is_ascii_digit();
        let date = before
            && digits(i..i + 4)
            && b[i + 4] == b'-'
            && digits(i + 5..i + 7)
            && b[i + 7] == b'-'
            && digits(i + 8..i + 10)
            && &text[i..i + 2] == "20";
        let time = text[i + 10..]
            .trim_start()
            .as_bytes()
            .get(..3)
            .is_some_and(|t| t[0].is_ascii_digit() && t[1].is_ascii_digit() && t[2] == b':');
        date && !time
    })
}

/// Whether `text` names an issue by number (the word, then a number, with or without `#`).
fn has_issue_number(text: &str) -> bool {
    let lower = text.to_lowercase();
    lower.match_indices("issue").any(|(i, _)| {
        let rest = lower[i + 5..].trim_start_matches([' ', '#']);
        rest.len() < lower[i + 5..].len() && rest.starts_with(|c: char| c.is_ascii_digit())
    })
}

/// The comment a line ends with: from the first `//` outside a string literal.
fn comment_of(line: &str) -> Option<&str> {
    let mut in_string = false;
    let mut escaped = false;
    for (i, c) in line.char_indices() {
        match c {
            _ if escaped => escaped = false,
            '\\' if in_string => escaped = true,
            '"' => in_string = !in_string,
            '/' if !in_string && line[i..].starts_with("//") => return Some(&line[i..]),
            _ => {}
        }
    }
    None
}

#[test]
fn no_comment_carries_a_date_or_an_issue_number() {
    // Code says what is true now; when something was measured, and which issue asked for it,
    // belong in docs/ and the history.
    let mut problems = Vec::new();
    for s in sources() {
        for (k, line) in s.text.lines().enumerate() {
            let Some(comment) = comment_of(line) else {
                continue;
            };
            if has_date(comment) || has_issue_number(comment) {
                problems.push(format!("{}:{}: {}", s.rel, k + 1, line.trim()));
            }
        }
    }
    fail("a comment with a date or an issue number", &problems);
}

#[test]
fn dates_and_issue_numbers_are_recognised() {
    assert!(has_date("// measured on 2026-11-29: legs"));
    assert!(!has_date("// 2026-03-01 00:00:00 UTC = 1772323200 s."));
    assert!(!has_date("// 12026-11-29 and 1-2-3"));
    assert!(has_issue_number("//! issue 29's timing targets"));
    assert!(has_issue_number("// see Issue #4"));
    assert!(!has_issue_number("// an issue the radio has"));
    assert_eq!(comment_of(r#"f("a // b"); // c"#), Some("// c"));
    assert_eq!(comment_of(r#"f("a // b");"#), None);
}

#[test]
fn no_two_files_import_each_other() {
    let sources = sources();
    // file -> (imported file -> first line importing it)
    let mut edges: BTreeMap<String, BTreeMap<String, usize>> = BTreeMap::new();
    for s in sources.iter().filter(|s| s.rel.starts_with("src/")) {
        let own = edges.entry(s.rel.clone()).or_default();
        for (n, _) in s.non_test() {
            for path in paths(&s.code, n - 1) {
                let Some(target) = resolve(s, &path) else {
                    continue;
                };
                // A module's own parents declare it; using them is no circle.
                let parent_dir = target
                    .strip_suffix("/mod.rs")
                    .map(|d| format!("{d}/"))
                    .unwrap_or_default();
                let is_ancestor = !parent_dir.is_empty() && s.rel.starts_with(&parent_dir);
                if target != s.rel && !is_ancestor {
                    own.entry(target).or_insert(n);
                }
            }
        }
    }
    let mut problems = Vec::new();
    for component in strongly_connected(&edges) {
        let members: BTreeSet<&String> = component.iter().collect();
        let mut circle = Vec::new();
        for from in &component {
            for (to, line) in &edges[from] {
                if members.contains(to) {
                    circle.push(format!("{from}:{line} imports {to}"));
                }
            }
        }
        problems.push(format!("import circle: {}", circle.join("; ")));
    }
    fail("files that import each other", &problems);
}

/// The strongly connected components of more than one file (Tarjan).
fn strongly_connected(edges: &BTreeMap<String, BTreeMap<String, usize>>) -> Vec<Vec<String>> {
    struct State<'a> {
        edges: &'a BTreeMap<String, BTreeMap<String, usize>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on_stack: BTreeSet<&'a str>,
        out: Vec<Vec<String>>,
    }
    fn visit<'a>(st: &mut State<'a>, v: &'a str) {
        let i = st.index.len();
        st.index.insert(v, i);
        st.low.insert(v, i);
        st.stack.push(v);
        st.on_stack.insert(v);
        if let Some(targets) = st.edges.get(v) {
            for w in targets.keys() {
                let w = w.as_str();
                if !st.index.contains_key(w) {
                    visit(st, w);
                    let low = st.low[v].min(st.low[w]);
                    st.low.insert(v, low);
                } else if st.on_stack.contains(w) {
                    let low = st.low[v].min(st.index[w]);
                    st.low.insert(v, low);
                }
            }
        }
        if st.low[v] == st.index[v] {
            let mut component = Vec::new();
            while let Some(w) = st.stack.pop() {
                st.on_stack.remove(w);
                component.push(w.to_string());
                if w == v {
                    break;
                }
            }
            if component.len() > 1 {
                component.sort();
                st.out.push(component);
            }
        }
    }
    let mut st = State {
        edges,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in edges.keys() {
        if !st.index.contains_key(v.as_str()) {
            visit(&mut st, v);
        }
    }
    st.out
}

/// `a/./b/../c` as `a/c`; None when it climbs out of the repository.
fn normalise(path: &Path) -> Option<PathBuf> {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                if !out.pop() {
                    return None;
                }
            }
            Component::Normal(part) => out.push(part),
            _ => return None,
        }
    }
    Some(out)
}

/// The module a `//!` doc documents: its path, and whether its file is a directory's mod.rs
/// (whose children are its submodules) rather than a leaf (whose neighbours are its siblings).
struct DocModule {
    path: Vec<String>,
    directory: bool,
}

/// The problems with the repository paths, `.md` files and module paths one document line
/// names; `dir` is the document's directory (from the root), `module` the module path of a
/// `//!` doc's file (for `super::x` and sibling modules).
fn named_paths(line: &str, dir: &str, module: Option<&DocModule>) -> Vec<String> {
    let mut problems = Vec::new();
    let token_chars = |c: char| c.is_alphanumeric() || matches!(c, '_' | '-' | '.' | '/');
    for token in line.split(|c: char| !token_chars(c)) {
        let token = token.trim_end_matches('.');
        let extension_only = token.starts_with('.') && !token.contains('/');
        if token.is_empty() || token.contains("//") || token.starts_with('/') || extension_only {
            continue;
        }
        let upstream_source = [".c", ".h", ".cpp", ".hpp", ".py", ".cc"]
            .iter()
            .any(|e| token.ends_with(e));
        let ours = REPO_DIRS.iter().any(|d| token.starts_with(d)) && !upstream_source;
        if !(ours || token.ends_with(".md") || token.starts_with("../")) {
            continue;
        }
        let exists = [Path::new(dir).join(token), PathBuf::from(token)]
            .iter()
            .filter_map(|p| normalise(p))
            .any(|p| root().join(p).exists());
        if !exists {
            problems.push(format!("`{token}` does not exist in the repository"));
        }
    }
    // Module paths in backticks; a command (`cargo test ... service::a_test`) names no module.
    for quoted in line.split('`').skip(1).step_by(2) {
        if quoted.starts_with("cargo ") || quoted.starts_with("emplan ") {
            continue;
        }
        for token in quoted.split(|c: char| !(is_ident_char(c) || c == ':')) {
            if let Some(problem) = module_path_problem(token, module) {
                problems.push(problem);
            }
        }
    }
    problems
}

/// What is wrong with a module path like `link::readback::verify` named in a document: the
/// longest prefix that is a module of src/ must be followed by nothing or by a name its file
/// mentions. Paths that start with no module of src/ (std, other crates) are not checked.
fn module_path_problem(token: &str, module: Option<&DocModule>) -> Option<String> {
    if !token.contains("::") || token.starts_with(':') || token.ends_with(':') {
        return None;
    }
    let mut segments: Vec<String> = token.split("::").map(str::to_string).collect();
    if segments.iter().any(|s| s.is_empty()) {
        return None;
    }
    if matches!(segments[0].as_str(), "crate" | "emplan") {
        segments.remove(0);
    }
    let mut base: Vec<String> = Vec::new();
    if segments.first().map(String::as_str) == Some("super") {
        base = module?.path.clone();
        while segments.first().map(String::as_str) == Some("super") {
            base.pop()?;
            segments.remove(0);
        }
    } else if module_file(&segments[..1]).is_none() {
        // A submodule or a sibling of the documented file, as `bound::dfj_bound` in src/tour/.
        let module = module?;
        base = module.path.clone();
        if !module.directory {
            base.pop();
        }
        module_file(&[base.clone(), segments[..1].to_vec()].concat())?;
    }
    let mut k = 0;
    while k < segments.len()
        && module_file(&[base.clone(), segments[..=k].to_vec()].concat()).is_some()
    {
        k += 1;
    }
    if k == 0 || k == segments.len() {
        return None;
    }
    let file = module_file(&[base, segments[..k].to_vec()].concat())?;
    let name = &segments[k];
    let text = std::fs::read_to_string(root().join(&file)).unwrap_or_default();
    (!defines(&text, name)).then(|| format!("`{token}`: {file} defines no `{name}`"))
}

/// Whether a file defines `name` (fn, type, const, module, macro...) or re-exports it.
fn defines(text: &str, name: &str) -> bool {
    let mut in_pub_use = false;
    for line in blank(text).lines() {
        let words = identifiers(line);
        let trimmed = line.trim_start();
        in_pub_use |= trimmed.starts_with("pub use") || trimmed.starts_with("pub(crate) use");
        if in_pub_use && words.iter().any(|(_, w)| *w == name) {
            return true;
        }
        if line.contains(';') {
            in_pub_use = false;
        }
        let keywords = [
            "fn",
            "struct",
            "enum",
            "const",
            "static",
            "type",
            "trait",
            "mod",
            "union",
            "macro_rules",
        ];
        if words
            .windows(2)
            .any(|w| w[1].1 == name && keywords.contains(&w[0].1))
        {
            return true;
        }
    }
    false
}

#[test]
fn every_path_a_document_names_exists() {
    let mut problems = Vec::new();
    let mut documents = Vec::new();
    walk(
        root(),
        &|p| p.extension().is_some_and(|e| e == "md"),
        &mut documents,
    );
    documents.sort();
    assert!(
        documents.iter().any(|d| d == "ARCHITECTURE.md"),
        "no ARCHITECTURE.md among {documents:?}"
    );
    for doc in &documents {
        let text = std::fs::read_to_string(root().join(doc)).expect("readable document");
        let dir = doc.rsplit_once('/').map_or("", |(d, _)| d);
        for (k, line) in text.lines().enumerate() {
            for problem in named_paths(line, dir, None) {
                problems.push(format!("{doc}:{}: {problem}", k + 1));
            }
        }
    }
    for s in sources() {
        let dir = s.rel.rsplit_once('/').map_or("", |(d, _)| d).to_string();
        let module = s.rel.starts_with("src/").then(|| DocModule {
            path: s.module_path(),
            directory: s.rel.ends_with("/mod.rs") || s.rel == "src/lib.rs",
        });
        for (k, line) in s.text.lines().enumerate() {
            let Some(doc) = line.trim_start().strip_prefix("//!") else {
                continue;
            };
            for problem in named_paths(doc, &dir, module.as_ref()) {
                problems.push(format!("{}:{}: {problem}", s.rel, k + 1));
            }
        }
    }
    fail(
        "documents naming what is not there (paths, .md files, module paths)",
        &problems,
    );
}
