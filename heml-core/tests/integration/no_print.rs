//! The library crates never write to stdout or stderr: an embedder (a GUI, a Python
//! host, a haptic loop) must be able to silence or route every message, so the
//! library reports through the `log` facade and through returned values only.
//!
//! This test reads the sources of the library crates (heml-core, and the workspace's
//! heml-materials, heml-integrators and heml-derive when run inside the workspace) and
//! fails on any `println!`, `print!`, `eprintln!`, `eprint!`, `dbg!` or call to
//! `stdout()` / `stderr()` in library code. To be robust rather than a plain grep it
//! first blanks out comments (so doc examples may print), string and character
//! literals (so a message may mention `println!`), then every item under
//! `#[cfg(test)]` (inline test modules and helpers) and every file that is a
//! `#[cfg(test)] mod name;` (e.g. `system/tests.rs`). The scanner itself is tested on
//! a synthetic source below, so a broken scanner cannot pass silently.

use std::path::{Path, PathBuf};

/// Macros that print.
const PRINT_MACROS: [&str; 5] = ["println", "print", "eprintln", "eprint", "dbg"];
/// Functions whose call hands out a process stream.
const STREAMS: [&str; 2] = ["stdout", "stderr"];

fn is_ident(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// The source with comments and string/char literals replaced by spaces (line breaks
/// kept, so line numbers stay right).
fn strip(src: &str) -> String {
    let c: Vec<char> = src.chars().collect();
    let mut out: Vec<char> = Vec::with_capacity(c.len());
    let blank = |out: &mut Vec<char>, ch: char| out.push(if ch == '\n' { '\n' } else { ' ' });
    let mut i = 0;
    while i < c.len() {
        let prev_ident = i > 0 && is_ident(c[i - 1]);
        if c[i] == '/' && c.get(i + 1) == Some(&'/') {
            while i < c.len() && c[i] != '\n' {
                blank(&mut out, c[i]);
                i += 1;
            }
        } else if c[i] == '/' && c.get(i + 1) == Some(&'*') {
            // block comments nest in Rust
            let mut depth = 0;
            loop {
                if i >= c.len() {
                    break;
                }
                if c[i] == '/' && c.get(i + 1) == Some(&'*') {
                    depth += 1;
                    out.extend([' ', ' ']);
                    i += 2;
                } else if c[i] == '*' && c.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    out.extend([' ', ' ']);
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    blank(&mut out, c[i]);
                    i += 1;
                }
            }
        } else if !prev_ident && (c[i] == 'r' || (c[i] == 'b' && c.get(i + 1) == Some(&'r'))) && {
            // raw string r"…", r#"…"#, br#"…"#
            let mut j = i + if c[i] == 'b' { 2 } else { 1 };
            while c.get(j) == Some(&'#') {
                j += 1;
            }
            c.get(j) == Some(&'"')
        } {
            let mut j = i + if c[i] == 'b' { 2 } else { 1 };
            let mut hashes = 0;
            while c[j] == '#' {
                hashes += 1;
                j += 1;
            }
            j += 1; // opening quote
            loop {
                if j >= c.len() {
                    break;
                }
                if c[j] == '"' && (1..=hashes).all(|h| c.get(j + h) == Some(&'#')) {
                    j += 1 + hashes;
                    break;
                }
                j += 1;
            }
            for &ch in &c[i..j.min(c.len())] {
                blank(&mut out, ch);
            }
            i = j;
        } else if c[i] == '"' {
            blank(&mut out, c[i]);
            i += 1;
            while i < c.len() && c[i] != '"' {
                if c[i] == '\\' {
                    blank(&mut out, c[i]);
                    i += 1;
                }
                if i < c.len() {
                    blank(&mut out, c[i]);
                    i += 1;
                }
            }
            if i < c.len() {
                blank(&mut out, c[i]);
                i += 1;
            }
        } else if c[i] == '\'' && (c.get(i + 1) == Some(&'\\') || c.get(i + 2) == Some(&'\'')) {
            // a char literal ('x', '\n', '\''); a lifetime ('a) has no closing quote
            let mut j = i + 1;
            if c[j] == '\\' {
                j += 2;
            } else {
                j += 1;
            }
            while j < c.len() && c[j] != '\'' {
                j += 1;
            }
            for &ch in &c[i..(j + 1).min(c.len())] {
                blank(&mut out, ch);
            }
            i = j + 1;
        } else {
            out.push(c[i]);
            i += 1;
        }
    }
    out.into_iter().collect()
}

/// Skips whitespace from `i`.
fn skip_ws(c: &[char], mut i: usize) -> usize {
    while i < c.len() && c[i].is_whitespace() {
        i += 1;
    }
    i
}

/// The index of the bracket closing the one `open` at `at` (or the end of `c`).
fn closing(c: &[char], at: usize, open: char, close: char) -> usize {
    let mut depth = 0;
    for (k, &ch) in c.iter().enumerate().skip(at) {
        if ch == open {
            depth += 1;
        } else if ch == close {
            depth -= 1;
            if depth == 0 {
                return k;
            }
        }
    }
    c.len()
}

/// If an attribute `#[…]` starts at `i`: (its end, whether it is `#[cfg(test)]`).
fn attribute(c: &[char], i: usize) -> Option<(usize, bool)> {
    if c.get(i) != Some(&'#') {
        return None;
    }
    let j = skip_ws(c, i + 1);
    if c.get(j) != Some(&'[') {
        return None;
    }
    let k = closing(c, j, '[', ']');
    let body: String = c[j + 1..k.min(c.len())]
        .iter()
        .filter(|ch| !ch.is_whitespace())
        .collect();
    Some((k + 1, body == "cfg(test)"))
}

/// Blanks out every item under `#[cfg(test)]` in stripped source and returns the
/// names of the out-of-line modules declared there (`#[cfg(test)] mod name;`).
fn drop_test_items(code: &str) -> (String, Vec<String>) {
    let mut c: Vec<char> = code.chars().collect();
    let mut test_mods = Vec::new();
    let mut i = 0;
    while i < c.len() {
        let Some((end, is_test)) = attribute(&c, i) else {
            i += 1;
            continue;
        };
        if !is_test {
            i = end;
            continue;
        }
        // further attributes, then the item up to its `;` or its balanced `{…}`
        let mut j = skip_ws(&c, end);
        while let Some((e, _)) = attribute(&c, j) {
            j = skip_ws(&c, e);
        }
        let head: String = c[j..].iter().take_while(|&&ch| ch != ';' && ch != '{').collect();
        let words: Vec<&str> = head.split_whitespace().collect();
        if let [.., "mod", name] = words.as_slice() {
            if c.get(j + head.chars().count()) == Some(&';') {
                test_mods.push(name.to_string());
            }
        }
        let mut k = j + head.chars().count();
        if c.get(k) == Some(&'{') {
            k = closing(&c, k, '{', '}');
        }
        let stop = (k + 1).min(c.len());
        for ch in &mut c[i..stop] {
            if *ch != '\n' {
                *ch = ' ';
            }
        }
        i = stop;
    }
    (c.into_iter().collect(), test_mods)
}

/// `(line, what)` of every print or stream call in the library part of `src`.
fn prints(src: &str) -> (Vec<(usize, String)>, Vec<String>) {
    let (code, test_mods) = drop_test_items(&strip(src));
    let mut found = Vec::new();
    for (n, line) in code.lines().enumerate() {
        let l: Vec<char> = line.chars().collect();
        let mut i = 0;
        while i < l.len() {
            if !is_ident(l[i]) || (i > 0 && is_ident(l[i - 1])) {
                i += 1;
                continue;
            }
            let end = (i..l.len()).find(|&k| !is_ident(l[k])).unwrap_or(l.len());
            let word: String = l[i..end].iter().collect();
            let next = l[skip_ws(&l, end)..].first().copied();
            if (PRINT_MACROS.contains(&word.as_str()) && next == Some('!'))
                || (STREAMS.contains(&word.as_str()) && next == Some('('))
            {
                found.push((n + 1, line.trim().to_string()));
            }
            i = end;
        }
    }
    (found, test_mods)
}

/// Where `mod name;` declared in `file` lives: beside a `mod.rs`/`lib.rs`/`main.rs`,
/// else in the folder named after the file.
fn module_dir(file: &Path) -> PathBuf {
    let parent = file.parent().unwrap().to_path_buf();
    match file.file_name().and_then(|n| n.to_str()) {
        Some("mod.rs" | "lib.rs" | "main.rs") => parent,
        _ => parent.join(file.file_stem().unwrap()),
    }
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
        let p = entry.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// Every print in the library files of the crate whose sources are under `src`.
fn crate_prints(src: &Path) -> (usize, Vec<String>) {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    files.sort();
    // test-only files and folders, found from their declarations
    let mut test_only: Vec<PathBuf> = Vec::new();
    let mut scanned = Vec::new();
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap();
        let (found, mods) = prints(&text);
        for m in mods {
            let dir = module_dir(f);
            test_only.push(dir.join(format!("{m}.rs")));
            test_only.push(dir.join(&m));
        }
        scanned.push((f.clone(), found));
    }
    let mut bad = Vec::new();
    let mut n = 0;
    for (f, found) in scanned {
        if test_only.iter().any(|t| f.starts_with(t)) {
            continue;
        }
        n += 1;
        for (line, text) in found {
            bad.push(format!("{}:{line}: {text}", f.display()));
        }
    }
    (n, bad)
}

#[test]
fn library_code_never_prints() {
    let core = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut crates = vec![core.join("src")];
    // inside the workspace, the other library crates too
    let root = core.parent().unwrap();
    if std::fs::read_to_string(root.join("Cargo.toml")).is_ok_and(|t| t.contains("[workspace]")) {
        for member in ["materials", "integrators", "heml-derive"] {
            let src = root.join(member).join("src");
            assert!(src.is_dir(), "{}: library crate moved? update this test", src.display());
            crates.push(src);
        }
    }
    let mut bad = Vec::new();
    for src in &crates {
        let (n, found) = crate_prints(src);
        assert!(n > 0, "{}: no library files found", src.display());
        bad.extend(found);
    }
    assert!(
        bad.is_empty(),
        "library code must log through the `log` facade (log::warn!/info!/debug!) \
         or return what it has to say, not print:\n{}",
        bad.join("\n")
    );
}

#[test]
fn the_scanner_sees_prints_only_in_library_code() {
    let src = r####"
//! println!("in a doc comment");
/* eprintln!("in a /* nested */ block comment"); */
const S: &str = "println!(\"in a string\")";
const R: &str = r#"dbg!("in a raw string")"#;
const C: char = '"';
fn lifetime<'a>(x: &'a str) -> &'a str { x }
fn real() {
    eprintln!("warning");
    let _ = std::io::stderr ();
    let w = writeln!(out, "fine"); let p = my_print!("fine too");
}
#[cfg(test)]
mod tests {
    fn t() { println!("in a test"); { dbg!(1); } }
}
#[cfg(test)]
fn helper() { print!("test helper"); }
#[cfg(test)]
mod more_tests;
fn after() { print !("after the test items"); }
"####;
    let (found, mods) = prints(src);
    let lines: Vec<usize> = found.iter().map(|(l, _)| *l).collect();
    assert_eq!(lines, [9, 10, 21], "{found:?}");
    assert_eq!(mods, ["more_tests"]);
    let dir = module_dir(Path::new("src/system/mod.rs"));
    assert_eq!(dir, Path::new("src/system"));
    assert_eq!(
        module_dir(Path::new("src/mesh/quality.rs")),
        Path::new("src/mesh/quality")
    );
}
