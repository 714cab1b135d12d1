//! Architecture invariant: the render engine knows nothing of HTTP, async runtimes or the
//! database, and never imports the server or job modules (ARCHITECTURE.md).

use std::path::Path;

fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

#[test]
fn render_engine_does_not_depend_on_the_server() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/render");
    let mut files = Vec::new();
    rust_files(&root, &mut files);
    assert!(files.len() > 10, "found the engine's sources");
    let forbidden = [
        "tokio",
        "axum",
        "hyper",
        "rusqlite",
        "tower",
        "sqlx",
        "crate::server",
        "crate::farm",
        "photonbox::farm",
        "crate::jobs",
        "photonbox::server",
        "photonbox::jobs",
        "println!",
    ];
    for f in files {
        // Code only: comments may name what the engine stays clear of.
        let text: String = std::fs::read_to_string(&f)
            .unwrap()
            .lines()
            .filter(|l| !l.trim_start().starts_with("//"))
            .collect::<Vec<_>>()
            .join("\n");
        // A module of unit tests may print what it measured.
        let test_module = f.file_name().is_some_and(|n| n == "tests.rs");
        for word in forbidden {
            if test_module && word == "println!" {
                continue;
            }
            assert!(
                !text.contains(word),
                "{} mentions `{word}`: the engine must stay independent of the server",
                f.display()
            );
        }
    }
}

/// The sources of `dir` (recursively), each as (path, code lines): comments and the text
/// of string and char literals blanked, so that only code is searched and braces counted.
fn code_of(dir: &Path) -> Vec<(std::path::PathBuf, Vec<String>)> {
    let mut files = Vec::new();
    rust_files(dir, &mut files);
    files.sort();
    files
        .into_iter()
        .map(|f| {
            let text = std::fs::read_to_string(&f).unwrap();
            (f, strip(&text).lines().map(str::to_string).collect())
        })
        .collect()
}

/// `text` with comments and literal contents replaced by spaces (line breaks kept).
fn strip(text: &str) -> String {
    let b: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    let blank = |c: char| if c == '\n' { '\n' } else { ' ' };
    while i < b.len() {
        let c = b[i];
        let next = b.get(i + 1).copied();
        if c == '/' && next == Some('/') {
            while i < b.len() && b[i] != '\n' {
                out.push(' ');
                i += 1;
            }
        } else if c == '/' && next == Some('*') {
            while i < b.len() && !(b[i] == '*' && b.get(i + 1) == Some(&'/')) {
                out.push(blank(b[i]));
                i += 1;
            }
            out.push_str("  ");
            i += 2;
        } else if c == 'r' && (next == Some('"') || next == Some('#')) {
            // A raw string: r"..." or r#"..."#.
            let mut j = i + 1;
            let mut hashes = 0;
            while b.get(j) == Some(&'#') {
                hashes += 1;
                j += 1;
            }
            if b.get(j) != Some(&'"') {
                out.push(c);
                i += 1;
                continue;
            }
            let close: String = std::iter::once('"')
                .chain("#".repeat(hashes).chars())
                .collect();
            out.push_str("r\"");
            j += 1;
            while j < b.len() && !b[j..].iter().collect::<String>().starts_with(&close) {
                out.push(blank(b[j]));
                j += 1;
            }
            out.push('"');
            i = j + close.len();
        } else if c == '"' {
            out.push('"');
            i += 1;
            while i < b.len() && b[i] != '"' {
                if b[i] == '\\' {
                    out.push(' ');
                    i += 1;
                }
                if i < b.len() {
                    out.push(blank(b[i]));
                }
                i += 1;
            }
            out.push('"');
            i += 1;
        } else if c == '\'' && (b.get(i + 2) == Some(&'\'') || next == Some('\\')) {
            // A char literal ('{', '\n'); a lifetime has no closing quote.
            let end = (i + 1..b.len())
                .find(|&j| b[j] == '\'' && j > i + 1)
                .unwrap_or(i);
            out.push_str(&" ".repeat(end - i + 1));
            i = end + 1;
        } else {
            out.push(c);
            i += 1;
        }
    }
    out
}

/// Adding an integrator is a variant of `spec::Integrator` (its settings, name and form
/// fields in src/spec/) and an arm of the engine's entry point (src/render/run/): no other
/// module names an integrator to decide what to do. Fails on any use of a variant of
/// `Integrator` or `IntegratorName`, or an integrator's name as a string, elsewhere in src/.
#[test]
fn only_the_spec_and_the_engine_entry_point_dispatch_on_the_integrator() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let allowed = [root.join("src/spec"), root.join("src/render/run")];
    let mut found = Vec::new();
    for (f, lines) in code_of(&root.join("src")) {
        // Tests may name the integrators they test.
        let test_module = f.file_name().is_some_and(|n| n == "tests.rs");
        if test_module || allowed.iter().any(|a| f.starts_with(a)) {
            continue;
        }
        let raw = std::fs::read_to_string(&f).unwrap();
        for (n, (line, raw_line)) in lines.iter().zip(raw.lines()).enumerate() {
            let variant = ["Integrator::", "IntegratorName::", "IntegratorKind"]
                .iter()
                .any(|p| line.contains(p));
            // Names as strings: the literal's text is blanked in `line`, so read it raw
            // where the code has a literal.
            let name = ["\"raytrace\"", "\"photon\"", "\"ppm\""]
                .iter()
                .any(|p| raw_line.contains(p) && line.contains('"'));
            if variant || name {
                found.push(format!("{}:{}: {}", f.display(), n + 1, raw_line.trim()));
            }
        }
    }
    assert!(
        found.is_empty(),
        "integrator dispatch outside src/spec and src/render/run:\n{}",
        found.join("\n")
    );
}

/// Files that fit in a head, functions named after the phase they implement: no file in
/// src/ over 400 lines, no function over 80 lines outside tests.
#[test]
fn files_and_functions_stay_short() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut long = Vec::new();
    for (f, lines) in code_of(&root.join("src")) {
        if lines.len() > 400 {
            long.push(format!("{}: {} lines", f.display(), lines.len()));
        }
        // A module of tests in a file of its own (`#[cfg(test)] mod tests;`).
        let test_file = f.file_name().is_some_and(|n| n == "tests.rs");
        for (name, start, len) in functions(&lines).into_iter().filter(|_| !test_file) {
            if len > 80 {
                long.push(format!("{}:{start}: fn {name}: {len} lines", f.display()));
            }
        }
    }
    assert!(long.is_empty(), "too long:\n{}", long.join("\n"));
}

/// (name, first line, lines) of every function with a body outside `#[cfg(test)]` modules
/// and `#[test]` functions.
fn functions(lines: &[String]) -> Vec<(String, usize, usize)> {
    let mut out = Vec::new();
    let mut depth = 0i32;
    // Open functions: (name, first line, depth outside its body).
    let mut open: Vec<(String, usize, i32)> = Vec::new();
    // Depth at which a skipped test item's body closes.
    let mut skip_until: Option<i32> = None;
    let mut test_attr = false;
    let mut pending: Option<(String, usize)> = None;
    for (n, line) in lines.iter().enumerate() {
        let t = line.trim();
        if t.starts_with("#[cfg(test)]") || t.starts_with("#[test]") {
            test_attr = true;
        } else if !(t.is_empty()
            || t.starts_with("#[")
            || t.starts_with("mod ")
            || fn_name(t).is_some())
        {
            // The attribute was on something else (a `use`, a constant).
            test_attr = false;
        }
        if skip_until.is_none()
            && let Some(name) = fn_name(t)
        {
            if test_attr {
                skip_until = Some(depth);
                test_attr = false;
            } else if !t.ends_with(';') {
                pending = Some((name, n + 1));
            }
        } else if test_attr && skip_until.is_none() && t.starts_with("mod ") {
            skip_until = Some(depth);
            test_attr = false;
        }
        for c in line.chars() {
            match c {
                '{' => {
                    if let Some((name, start)) = pending.take() {
                        open.push((name, start, depth));
                    }
                    depth += 1;
                }
                '}' => {
                    depth -= 1;
                    if open.last().is_some_and(|o| o.2 == depth) {
                        let (name, start, _) = open.pop().unwrap();
                        if skip_until.is_none() {
                            out.push((name, start, n + 2 - start));
                        }
                    }
                    if skip_until == Some(depth) {
                        skip_until = None;
                    }
                }
                ';' if depth == skip_until.unwrap_or(-1) => skip_until = None,
                _ => {}
            }
        }
    }
    out
}

/// The name of the function a line declares, if it does.
fn fn_name(line: &str) -> Option<String> {
    let words: Vec<&str> = line.split_whitespace().collect();
    let i = words.iter().position(|w| *w == "fn")?;
    let before_ok = words[..i].iter().all(|w| {
        w.starts_with("pub") || ["const", "async", "unsafe", "extern", "\"C\""].contains(w)
    });
    let name: String = words
        .get(i + 1)?
        .chars()
        .take_while(|c| c.is_alphanumeric() || *c == '_')
        .collect();
    (before_ok && !name.is_empty()).then_some(name)
}
