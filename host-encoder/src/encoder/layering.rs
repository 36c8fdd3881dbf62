//! The encoder's modules form layers without cycles: each uses only those below it. Read from
//! the sources, so a new `use` that breaks it fails here.

/// The encoder's modules from the bottom up: each may use only those of the layers before it
/// (and its own submodules), and the crate's coders ([`crate::entropy`], below them all). The
/// encoder's root (`mod.rs`, the public API, and `parts.rs`, its encode of images too large to
/// analyse whole) is above them all.
const LAYERS: &[&[&str]] = &[
    &["ids", "plane", "config"],
    &["error"],
    &["masking"],
    &["synthesis"],
    &["fit"],
    &["quantise"],
    &["candidates"],
    &["rate"],
    &["chroma"],
    &["writer"],
    &["analysis"],
];

/// What a path from an encoder module names.
#[derive(Debug, PartialEq, Eq)]
enum Use {
    /// A module of the encoder.
    Module(String),
    /// An item of the encoder's root, or of the crate's root (above every module).
    Root(String),
    /// Something of the crate outside the encoder that the encoder may use: its coders, or (in
    /// tests) the image reader.
    Outside,
}

fn layer(module: &str) -> Option<usize> {
    LAYERS.iter().position(|l| l.contains(&module))
}

fn identifier(text: &str) -> String {
    text.chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
        .collect()
}

/// The names a path continues with at `text`'s start: one, or each of a `{...}` group's.
fn names(text: &str) -> Vec<String> {
    let Some(group) = text.strip_prefix('{') else {
        return vec![identifier(text)];
    };
    let mut out = Vec::new();
    let (mut depth, mut start) = (0, 0);
    for (i, c) in group.char_indices() {
        match c {
            '{' => depth += 1,
            '}' if depth == 0 => {
                out.push(identifier(group[start..i].trim()));
                break;
            }
            '}' => depth -= 1,
            ',' if depth == 0 => {
                out.push(identifier(group[start..i].trim()));
                start = i + 1;
            }
            _ => {}
        }
    }
    out.retain(|n| !n.is_empty());
    out
}

/// What the code of a source file uses, outside comments. `depth`: how many `super::` lead from
/// the file's top level to the encoder (1 for `encoder/x.rs`, 2 for `encoder/x/y.rs`); inside a
/// file's `mod tests` one more.
fn uses(source: &str, depth: usize) -> Vec<Use> {
    let mut out = Vec::new();
    let mut in_tests = false;
    for line in source.lines() {
        in_tests |= line.starts_with("mod tests");
        let depth = depth + usize::from(in_tests);
        let mut rest = line.split("//").next().unwrap_or("");
        loop {
            let at = match (rest.find("crate::"), rest.find("super::")) {
                (Some(a), Some(b)) => a.min(b),
                (a, b) => match a.or(b) {
                    Some(at) => at,
                    None => break,
                },
            };
            let mut tail = &rest[at..];
            let mut supers = 0;
            while let Some(t) = tail.strip_prefix("super::") {
                supers += 1;
                tail = t;
            }
            if supers == 0 {
                tail = &tail["crate::".len()..];
                let first = identifier(tail);
                match first.as_str() {
                    "encoder" => {
                        let path = tail["encoder".len()..].trim_start_matches("::");
                        out.extend(names(path).into_iter().map(classify));
                    }
                    "entropy" => out.push(Use::Outside),
                    "io" if in_tests => out.push(Use::Outside),
                    _ => out.push(Use::Root(first)),
                }
            } else if supers == depth {
                out.extend(names(tail).into_iter().map(classify));
            } else if supers > depth {
                out.push(Use::Root(identifier(tail)));
            }
            // Fewer: the file's own module.
            rest = tail;
        }
    }
    out
}

fn classify(name: String) -> Use {
    if layer(&name).is_some() {
        Use::Module(name)
    } else {
        Use::Root(name)
    }
}

/// The `.rs` files of module `module`: `module.rs` and those under `module/`, each with its
/// depth below the encoder.
fn files_of(module: &str) -> Vec<(std::path::PathBuf, usize)> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src/encoder");
    let mut files = vec![(dir.join(format!("{module}.rs")), 1)];
    if let Ok(entries) = std::fs::read_dir(dir.join(module)) {
        files.extend(entries.flatten().map(|e| (e.path(), 2)));
    }
    files
}

/// No module of the encoder uses one above it, nor the encoder's root: the layering has no
/// cycle.
#[test]
fn modules_use_only_the_layers_below() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src/encoder");
    // Every module file is in a layer.
    for entry in std::fs::read_dir(&dir)
        .expect("the encoder's sources")
        .flatten()
    {
        let path = entry.path();
        let name = path.file_stem().and_then(|n| n.to_str()).unwrap_or("");
        if path.extension().is_some_and(|e| e == "rs")
            && !["mod", "parts", "layering"].contains(&name)
        {
            assert!(layer(name).is_some(), "module {name} has no layer");
        }
    }
    let mut checked = 0;
    for (level, modules) in LAYERS.iter().enumerate() {
        for &module in *modules {
            for (file, depth) in files_of(module) {
                let text = std::fs::read_to_string(&file)
                    .unwrap_or_else(|e| panic!("{}: {e}", file.display()));
                for used in uses(&text, depth) {
                    match used {
                        Use::Module(m) if m == module => {}
                        Use::Module(m) => assert!(
                            layer(&m).is_some_and(|l| l < level),
                            "{} uses {m}, which is not below {module}",
                            file.display()
                        ),
                        Use::Root(item) => panic!(
                            "{} uses {item} of the root, which is above {module}",
                            file.display()
                        ),
                        Use::Outside => {}
                    }
                }
                checked += 1;
            }
        }
    }
    assert!(checked >= 12, "only {checked} files checked");
}

/// The reader finds what it must: paths by `super::` at each depth, groups, `crate::encoder::`,
/// and items of the root.
#[test]
fn uses_are_read_from_paths() {
    let source = "use super::fit::Fit;\n\
                  use super::{ids::{ModelId, ControlQuantiserId}, plane};\n\
                  use crate::encoder::rate::Plan; // super::writer in a comment\n\
                  use crate::entropy::BitCounter;\n\
                  use super::EncoderConfig;\n\
                  mod tests {\n\
                  use super::*;\n\
                  use super::super::writer::write;\n\
                  use crate::io::load_luma;\n";
    let module = |m: &str| Use::Module(m.to_string());
    assert_eq!(
        uses(source, 1),
        vec![
            module("fit"),
            module("ids"),
            module("plane"),
            module("rate"),
            Use::Outside,
            Use::Root("EncoderConfig".to_string()),
            module("writer"),
            Use::Outside,
        ]
    );
}
