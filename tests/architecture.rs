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
        "crate::server",
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
        for word in forbidden {
            assert!(
                !text.contains(word),
                "{} mentions `{word}`: the engine must stay independent of the server",
                f.display()
            );
        }
    }
}
