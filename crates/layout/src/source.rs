//! Reading scripts: RON parsing with file:line:column errors, `base` and `include`
//! references, and a source map that locates items and edits for later error messages.

use crate::error::{LayoutError, Location};
use crate::script::{AssetDef, Edit, Item, Lighting, Script, V2, ViewSettings};
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

/// One script file's text, indexed for locating identifiers and string literals outside
/// comments.
#[derive(Debug, Clone)]
pub struct SourceFile {
    pub path: PathBuf,
    pub text: String,
    idents: HashMap<String, Vec<usize>>,
    strings: Vec<(String, usize)>,
    line_starts: Vec<usize>,
}

impl SourceFile {
    pub fn new(path: PathBuf, text: String) -> Self {
        let mut idents: HashMap<String, Vec<usize>> = HashMap::new();
        let mut strings = Vec::new();
        let b = text.as_bytes();
        let mut i = 0;
        while i < b.len() {
            let c = b[i];
            if c == b'/' && b.get(i + 1) == Some(&b'/') {
                while i < b.len() && b[i] != b'\n' {
                    i += 1;
                }
            } else if c == b'/' && b.get(i + 1) == Some(&b'*') {
                i += 2;
                while i + 1 < b.len() && !(b[i] == b'*' && b[i + 1] == b'/') {
                    i += 1;
                }
                i += 2;
            } else if c == b'"' {
                let start = i;
                i += 1;
                let mut s = Vec::new();
                while i < b.len() && b[i] != b'"' {
                    if b[i] == b'\\' && i + 1 < b.len() {
                        i += 1;
                    }
                    s.push(b[i]);
                    i += 1;
                }
                i += 1;
                strings.push((String::from_utf8_lossy(&s).into_owned(), start));
            } else if c.is_ascii_alphabetic() || c == b'_' {
                let start = i;
                while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_') {
                    i += 1;
                }
                idents.entry(text[start..i].to_string()).or_default().push(start);
            } else {
                i += 1;
            }
        }
        let mut line_starts = vec![0];
        line_starts.extend(text.match_indices('\n').map(|(k, _)| k + 1));
        SourceFile { path, text, idents, strings, line_starts }
    }

    /// Line and column (1-based, columns in characters) of a byte offset.
    pub fn location(&self, offset: usize) -> Location {
        let line = self.line_starts.partition_point(|&s| s <= offset);
        let start = self.line_starts[line - 1];
        let col = self.text[start..offset.min(self.text.len())].chars().count() + 1;
        Location { file: self.path.clone(), line, col }
    }

    /// Where the `nth` (0-based) occurrence of identifier `ident` stands.
    pub fn find_ident(&self, ident: &str, nth: usize) -> Location {
        let off = self.idents.get(ident).and_then(|v| v.get(nth)).copied().unwrap_or(0);
        self.location(off)
    }

    /// Where the first string literal equal to `s` stands, if any.
    pub fn find_string(&self, s: &str) -> Option<Location> {
        self.strings.iter().find(|(v, _)| v == s).map(|(_, off)| self.location(*off))
    }

    /// The place of the first string literal `s` at or after `after`, else `after` itself.
    pub fn find_string_after(&self, s: &str, after: &Location) -> Location {
        self.strings
            .iter()
            .map(|(v, off)| (v, self.location(*off)))
            .find(|(v, l)| *v == s && (l.line, l.col) >= (after.line, after.col))
            .map(|(_, l)| l)
            .unwrap_or_else(|| after.clone())
    }
}

/// A placement item with its place in the source and its children (for groups).
#[derive(Debug, Clone)]
pub struct ItemNode {
    pub item: Item,
    pub location: Location,
    pub file: usize,
    pub children: Vec<ItemNode>,
}

/// An edit with its place in the source.
#[derive(Debug, Clone)]
pub struct EditNode {
    pub edit: Edit,
    pub location: Location,
    pub file: usize,
}

/// An asset definition with the file that defined it (OBJ paths are relative to it).
#[derive(Debug, Clone)]
pub struct AssetEntry {
    pub def: AssetDef,
    pub file: usize,
    pub location: Location,
}

impl AssetEntry {
    /// Folder of the defining file, for relative paths inside the definition.
    pub fn base_dir<'a>(&self, script: &'a LoadedScript) -> &'a Path {
        script.files[self.file].path.parent().unwrap_or(Path::new("."))
    }
}

/// A script with its `base` chain and `include`s read: everything needed to resolve it.
#[derive(Debug, Clone)]
pub struct LoadedScript {
    pub name: String,
    pub path: PathBuf,
    pub files: Vec<SourceFile>,
    pub assets: BTreeMap<String, AssetEntry>,
    pub items: Vec<ItemNode>,
    pub edits: Vec<EditNode>,
    pub extent: Option<(V2, V2)>,
    pub views: Option<ViewSettings>,
    pub lighting: Option<Lighting>,
    /// Scene units per metre, as the script (or its base) records it.
    pub units_per_metre: Option<f32>,
}

fn ron_options() -> ron::Options {
    ron::Options::default().with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
}

/// Parse script text (no `base`/`include` resolution) with a located syntax error.
pub fn parse_script(path: &Path, text: &str) -> Result<Script, LayoutError> {
    ron_options().from_str::<Script>(text).map_err(|e| LayoutError::Syntax {
        location: Location {
            file: path.to_path_buf(),
            line: e.span.start.line,
            col: e.span.start.col,
        },
        message: e.code.to_string(),
    })
}

/// Serialise a script as pretty RON (the inverse of [`parse_script`]).
pub fn write_script(script: &Script) -> Result<String, LayoutError> {
    let cfg = ron::ser::PrettyConfig::new().struct_names(true).depth_limit(4).indentor("    ");
    let body = ron_options()
        .to_string_pretty(script, cfg)
        .map_err(|e| LayoutError::Write(e.to_string()))?;
    Ok(format!("#![enable(implicit_some)]\n{body}\n"))
}

/// Read a script file and everything it refers to.
pub fn load(path: &Path) -> Result<LoadedScript, LayoutError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| LayoutError::Io { path: path.to_path_buf(), source: e })?;
    load_str(path, &text)
}

/// Like [`load`], with the main file's text given (`path` names it in messages and anchors
/// relative references).
pub fn load_str(path: &Path, text: &str) -> Result<LoadedScript, LayoutError> {
    let mut loaded = LoadedScript {
        name: path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default(),
        path: path.to_path_buf(),
        files: Vec::new(),
        assets: BTreeMap::new(),
        items: Vec::new(),
        edits: Vec::new(),
        extent: None,
        views: None,
        lighting: None,
        units_per_metre: None,
    };
    let mut stack = Vec::new();
    load_into(&mut loaded, path, Some(text.to_string()), &mut stack, false)?;
    Ok(loaded)
}

fn canonical(p: &Path) -> PathBuf {
    std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf())
}

fn load_into(
    out: &mut LoadedScript,
    path: &Path,
    text: Option<String>,
    stack: &mut Vec<PathBuf>,
    assets_only: bool,
) -> Result<(), LayoutError> {
    let key = canonical(path);
    if stack.contains(&key) {
        let cycle = stack.iter().chain(std::iter::once(&key)).map(|p| p.display().to_string());
        return Err(LayoutError::Cycle {
            path: path.to_path_buf(),
            cycle: cycle.collect::<Vec<_>>().join(" -> "),
        });
    }
    let text = match text {
        Some(t) => t,
        None => std::fs::read_to_string(path)
            .map_err(|e| LayoutError::Io { path: path.to_path_buf(), source: e })?,
    };
    let script = parse_script(path, &text)?;
    let file = out.files.len();
    out.files.push(SourceFile::new(path.to_path_buf(), text));
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    stack.push(key);

    if assets_only
        && (!script.layout.is_empty() || !script.edits.is_empty() || script.base.is_some())
    {
        let src = &out.files[file];
        return Err(LayoutError::Semantic {
            location: src.location(0),
            message: "an included file may only define assets (use `base` to extend a scene)"
                .into(),
        });
    }
    if let Some(base) = &script.base {
        load_into(out, &dir.join(base), None, stack, false)?;
    }
    for inc in &script.include {
        let inc_path = dir.join(inc);
        if !inc_path.exists() {
            let src = &out.files[file];
            let location = src.find_string(inc).unwrap_or_else(|| src.location(0));
            stack.pop();
            return Err(LayoutError::Semantic {
                location,
                message: format!("included file {} does not exist", inc_path.display()),
            });
        }
        load_into(out, &inc_path, None, stack, true)?;
    }
    stack.pop();

    for (name, def) in script.assets {
        let src = &out.files[file];
        let location = src.find_string(&name).unwrap_or_else(|| src.location(0));
        out.assets.insert(name, AssetEntry { def, file, location });
    }
    if !assets_only {
        if let Some(n) = script.name {
            out.name = n;
        }
        out.extent = script.extent.or(out.extent);
        out.views = script.views.or(out.views.take());
        out.lighting = script.lighting.or(out.lighting.take());
        out.units_per_metre = script.units_per_metre.or(out.units_per_metre);
        let mut counters: HashMap<&'static str, usize> = HashMap::new();
        for item in script.layout {
            let node = locate_item(&out.files[file], file, item, &mut counters);
            out.items.push(node);
        }
        for edit in script.edits {
            let n = counters.entry(edit.variant()).or_default();
            let location = out.files[file].find_ident(edit.variant(), *n);
            *n += 1;
            out.edits.push(EditNode { edit, location, file });
        }
    }
    Ok(())
}

/// Items are visited in document order (pre-order), so the k-th item of a variant is the
/// k-th occurrence of that variant's identifier in the file.
fn locate_item(
    src: &SourceFile,
    file: usize,
    item: Item,
    counters: &mut HashMap<&'static str, usize>,
) -> ItemNode {
    let n = counters.entry(item.variant()).or_default();
    let location = src.find_ident(item.variant(), *n);
    *n += 1;
    let children = match &item {
        Item::Group { children, .. } => {
            children.iter().cloned().map(|c| locate_item(src, file, c, counters)).collect()
        }
        _ => Vec::new(),
    };
    ItemNode { item, location, file, children }
}

/// Append the `edits` of the script at `path` to `script` (after its own edits), ignoring
/// that file's `base`: the same edit list can then be applied to another layout of the same
/// scene (e.g. one written against the ground-truth scene, applied to a mined layout whose
/// instances carry the ground-truth keys). The file may hold edits only. Returns how many
/// edits were added.
pub fn append_edits(script: &mut LoadedScript, path: &Path) -> Result<usize, LayoutError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| LayoutError::Io { path: path.to_path_buf(), source: e })?;
    let parsed = parse_script(path, &text)?;
    let file = script.files.len();
    script.files.push(SourceFile::new(path.to_path_buf(), text));
    let src = &script.files[file];
    if !parsed.layout.is_empty() || !parsed.assets.is_empty() || !parsed.include.is_empty() {
        let what = if parsed.layout.is_empty() { "assets" } else { "layout items" };
        let location = src
            .find_string(if parsed.layout.is_empty() { "assets" } else { "layout" })
            .unwrap_or_else(|| src.location(0));
        return Err(LayoutError::Semantic {
            location,
            message: format!(
                "an edit list may only hold `edits` (it has {what}); to add instances, write a script with `base:` naming the layout"
            ),
        });
    }
    let mut counters: HashMap<&'static str, usize> = HashMap::new();
    let n = parsed.edits.len();
    for edit in parsed.edits {
        let k = counters.entry(edit.variant()).or_default();
        let location = script.files[file].find_ident(edit.variant(), *k);
        *k += 1;
        script.edits.push(EditNode { edit, location, file });
    }
    Ok(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn appended_edits_apply_after_the_scripts_own_and_locate_instances() {
        let dir = std::env::temp_dir().join(format!("af-append-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let scene = "Scene(\n  assets: {\n    \"a\": Asset(parts: [Box(center: (0, 0, 0.5), size: (1, 1, 1), color: (1, 0, 0))]),\n  },\n  layout: [\n    Row(asset: \"a\", from: (0, 0), to: (4, 0), count: 3, name: \"r\"),\n  ],\n  edits: [Move(target: \"r[0]\", by: (0, 1))],\n)\n";
        let edits = "Scene(\n  base: \"elsewhere.ron\",\n  edits: [\n    Remove(\"r[1]\"),\n    Move(target: \"r[0]\", by: (1, 0)),\n  ],\n)\n";
        std::fs::write(dir.join("s.ron"), scene).unwrap();
        std::fs::write(dir.join("e.ron"), edits).unwrap();
        let mut script = load(&dir.join("s.ron")).unwrap();
        assert_eq!(append_edits(&mut script, &dir.join("e.ron")).unwrap(), 2);
        let catalog = crate::PartsCatalog::from_script(&script);
        let layout = crate::resolve(&script, &catalog).unwrap();
        let keys: Vec<&str> = layout.instances.iter().map(|i| i.key.as_str()).collect();
        assert_eq!(keys, ["r[0]", "r[2]"]);
        let r0 = &layout.instances[0];
        assert_eq!(r0.transform.position, glam::Vec2::new(1.0, 1.0), "both moves, in order");
        // the instance was last changed by the appended Move (e.ron line 5), placed at s.ron:6
        assert_eq!((r0.placed_at.line, r0.placed_at.col), (6, 5));
        let at = r0.location();
        assert!(at.file.ends_with("e.ron") && at.line == 5, "{at}");
        assert!(layout.instances[1].edited_at.is_none());
        // an edit list with layout items is refused, naming the file
        std::fs::write(dir.join("bad.ron"), "Scene(layout: [Instance(asset: \"a\", at: (0, 0))])")
            .unwrap();
        let e = append_edits(&mut load(&dir.join("s.ron")).unwrap(), &dir.join("bad.ron"));
        assert!(e.unwrap_err().to_string().contains("bad.ron:1:"));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn locations_skip_comments_and_strings() {
        let text = "// Row in a comment\nScene(\n  name: \"Row\",\n  layout: [\n    Row(asset: \"a\"),\n  ],\n)";
        let s = SourceFile::new("x.ron".into(), text.into());
        let l = s.find_ident("Row", 0);
        assert_eq!((l.line, l.col), (5, 5));
        let l = s.find_string("a").unwrap();
        assert_eq!((l.line, l.col), (5, 16));
    }

    #[test]
    fn syntax_errors_have_line_and_column() {
        let text = "Scene(\n  layout: [\n    Instance(asset: \"a\", at: (0, 0), yaww: 3),\n  ],\n)";
        let err = parse_script(Path::new("scene.ron"), text).unwrap_err();
        let msg = err.to_string();
        assert!(msg.starts_with("scene.ron:3:"), "{msg}");
        assert!(msg.contains("yaww"), "{msg}");
    }

    #[test]
    fn scripts_round_trip_through_ron() {
        let text = r##"Scene(
            name: "t",
            assets: { "a": Asset(parts: [Box(center: (0, 0, 0.5), size: (1, 1, 1), color: (1, 0, 0))]) },
            layout: [
                Ring(asset: "a", center: (0, 0), radius: 2, count: 5, face: Center),
                Group(on: "x[*]", children: [Instance(asset: "a", at: (0.1, 0))]),
                Along(asset: "a", path: [(0, 0), (3, 0)], spacing: 1.0, face: Toward(1, 2)),
            ],
            edits: [Remove("x[0]"), Move(target: "#3", by: (1, 0))],
        )"##;
        let s = parse_script(Path::new("t.ron"), text).unwrap();
        let back = parse_script(Path::new("t.ron"), &write_script(&s).unwrap()).unwrap();
        assert_eq!(s, back);
    }
}
