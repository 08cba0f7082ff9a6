//! Reading scripts: RON parsing with file:line:column errors, `base` and `include`
//! references, and a source map that locates items and edits for later error messages.

use crate::error::{LayoutError, Location};
use crate::limits::{Limit, Limits};
use crate::script::{AssetDef, Edit, Item, Lighting, Script, V2, ViewSettings};
use crate::validate;
use std::collections::{BTreeMap, HashMap};
use std::io::Read;
use std::path::{Path, PathBuf};

/// Bytes per block of the character-count index of a [`SourceFile`] (columns are counted in
/// characters: a column costs at most one block of counting, however long the line).
const CHAR_BLOCK: usize = 1024;

/// One script file's text, indexed for locating identifiers and string literals outside
/// comments. Every lookup is a hash lookup plus a binary search: locating all items of a
/// file takes time linear in its size.
#[derive(Debug, Clone)]
pub struct SourceFile {
    pub path: PathBuf,
    pub text: String,
    /// Byte offsets of every identifier, by identifier, ascending.
    idents: HashMap<String, Vec<usize>>,
    /// Byte offsets of the opening quote of every string literal, by value, ascending.
    strings: HashMap<String, Vec<usize>>,
    line_starts: Vec<usize>,
    /// Characters before byte `k * CHAR_BLOCK`, for every block.
    chars_before_block: Vec<usize>,
}

fn push_offset(map: &mut HashMap<String, Vec<usize>>, key: &str, offset: usize) {
    match map.get_mut(key) {
        Some(v) => v.push(offset),
        None => {
            map.insert(key.to_string(), vec![offset]);
        }
    }
}

/// Characters in `bytes` (UTF-8): the bytes that do not continue a character.
fn count_chars(bytes: &[u8]) -> usize {
    bytes.iter().filter(|&&b| (b & 0xC0) != 0x80).count()
}

impl SourceFile {
    pub fn new(path: PathBuf, text: String) -> Self {
        let mut idents: HashMap<String, Vec<usize>> = HashMap::new();
        let mut strings: HashMap<String, Vec<usize>> = HashMap::new();
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
                push_offset(&mut strings, &String::from_utf8_lossy(&s), start);
            } else if c.is_ascii_alphabetic() || c == b'_' {
                let start = i;
                while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_') {
                    i += 1;
                }
                push_offset(&mut idents, &text[start..i], start);
            } else {
                i += 1;
            }
        }
        let mut line_starts = vec![0];
        line_starts.extend(text.match_indices('\n').map(|(k, _)| k + 1));
        let mut chars_before_block = vec![0];
        for block in b.chunks(CHAR_BLOCK) {
            let before = chars_before_block.last().copied().unwrap_or(0);
            chars_before_block.push(before + count_chars(block));
        }
        SourceFile { path, text, idents, strings, line_starts, chars_before_block }
    }

    /// Characters before byte `offset` (at most the text's length).
    fn chars_before(&self, offset: usize) -> usize {
        let offset = offset.min(self.text.len());
        let block = offset / CHAR_BLOCK;
        self.chars_before_block[block]
            + count_chars(&self.text.as_bytes()[block * CHAR_BLOCK..offset])
    }

    /// Line and column (1-based, columns in characters) of a byte offset.
    pub fn location(&self, offset: usize) -> Location {
        let line = self.line_starts.partition_point(|&s| s <= offset);
        let start = self.line_starts[line - 1];
        let col = self.chars_before(offset) - self.chars_before(start) + 1;
        Location { file: self.path.clone(), line, col }
    }

    /// Byte offset of the `nth` (0-based) occurrence of identifier `ident` (0 if none).
    pub fn ident_offset(&self, ident: &str, nth: usize) -> usize {
        self.idents.get(ident).and_then(|v| v.get(nth)).copied().unwrap_or(0)
    }

    /// Where the `nth` (0-based) occurrence of identifier `ident` stands.
    pub fn find_ident(&self, ident: &str, nth: usize) -> Location {
        self.location(self.ident_offset(ident, nth))
    }

    /// Where the first string literal equal to `s` stands, if any.
    pub fn find_string(&self, s: &str) -> Option<Location> {
        self.strings.get(s).and_then(|v| v.first()).map(|&off| self.location(off))
    }

    /// The place of the first string literal `s` at or after the byte offset `after`, else
    /// the place of `after` itself.
    pub fn find_string_after(&self, s: &str, after: usize) -> Location {
        let found = self.strings.get(s).and_then(|v| v.get(v.partition_point(|&o| o < after)));
        self.location(found.copied().unwrap_or(after))
    }
}

/// A placement item with its place in the source and its children (for groups).
#[derive(Debug, Clone)]
pub struct ItemNode {
    pub item: Item,
    pub location: Location,
    /// Byte offset of [`Self::location`] in its file.
    pub offset: usize,
    pub file: usize,
    pub children: Vec<ItemNode>,
}

/// An edit with its place in the source.
#[derive(Debug, Clone)]
pub struct EditNode {
    pub edit: Edit,
    pub location: Location,
    /// Byte offset of [`Self::location`] in its file.
    pub offset: usize,
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
    /// Where the `views` in effect were written (for messages about them).
    pub views_at: Option<Location>,
    pub lighting: Option<Lighting>,
    /// Scene units per metre, as the script (or its base) records it.
    pub units_per_metre: Option<f32>,
    /// The limits the script was loaded with; [`crate::resolve()`] and [`append_edits`]
    /// apply them too.
    pub limits: Limits,
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

/// What a file that is not a regular file is, in words.
fn file_kind(meta: &std::fs::Metadata) -> &'static str {
    let t = meta.file_type();
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO";
        }
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    if t.is_dir() { "a folder" } else { "not a regular file" }
}

/// Read a script file: it must be a regular file (a FIFO could block forever, a device never
/// end) of at most [`Limits::max_file_bytes`]; the read itself stops after that many bytes,
/// so a file that grows while it is read stays bounded. `referenced_at` is the `base` or
/// `include` that names the file, for messages.
pub fn read_script_file(
    path: &Path,
    limits: &Limits,
    referenced_at: Option<&Location>,
) -> Result<String, LayoutError> {
    let io = |source| LayoutError::Io { path: path.to_path_buf(), source };
    let not_a_file = |meta: &std::fs::Metadata| LayoutError::NotAFile {
        path: path.to_path_buf(),
        kind: file_kind(meta),
        referenced_at: referenced_at.cloned(),
    };
    let too_large = |size: u64| LayoutError::TooLarge {
        path: path.to_path_buf(),
        size,
        limit: limits.max_file_bytes,
        referenced_at: referenced_at.cloned(),
    };
    let meta = std::fs::metadata(path).map_err(io)?;
    if !meta.is_file() {
        return Err(not_a_file(&meta));
    }
    if meta.len() > limits.max_file_bytes {
        return Err(too_large(meta.len()));
    }
    let file = std::fs::File::open(path).map_err(io)?;
    // the path may have been replaced between the two looks: check what was opened
    let meta = file.metadata().map_err(io)?;
    if !meta.is_file() {
        return Err(not_a_file(&meta));
    }
    let mut bytes = Vec::new();
    file.take(limits.max_file_bytes.saturating_add(1)).read_to_end(&mut bytes).map_err(io)?;
    let read = u64::try_from(bytes.len()).unwrap_or(u64::MAX);
    if read > limits.max_file_bytes {
        return Err(too_large(read));
    }
    String::from_utf8(bytes)
        .map_err(|e| io(std::io::Error::new(std::io::ErrorKind::InvalidData, e.utf8_error())))
}

/// Read a script file and everything it refers to, with the limits of the environment
/// ([`Limits::from_env`]).
pub fn load(path: &Path) -> Result<LoadedScript, LayoutError> {
    load_with(path, &Limits::from_env()?)
}

/// [`load`] with the given limits.
pub fn load_with(path: &Path, limits: &Limits) -> Result<LoadedScript, LayoutError> {
    let text = read_script_file(path, limits, None)?;
    load_str_with(path, &text, limits)
}

/// Like [`load`], with the main file's text given (`path` names it in messages and anchors
/// relative references).
pub fn load_str(path: &Path, text: &str) -> Result<LoadedScript, LayoutError> {
    load_str_with(path, text, &Limits::from_env()?)
}

/// [`load_str`] with the given limits.
pub fn load_str_with(
    path: &Path,
    text: &str,
    limits: &Limits,
) -> Result<LoadedScript, LayoutError> {
    let size = u64::try_from(text.len()).unwrap_or(u64::MAX);
    if size > limits.max_file_bytes {
        return Err(LayoutError::TooLarge {
            path: path.to_path_buf(),
            size,
            limit: limits.max_file_bytes,
            referenced_at: None,
        });
    }
    let mut loaded = LoadedScript {
        name: path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default(),
        path: path.to_path_buf(),
        files: Vec::new(),
        assets: BTreeMap::new(),
        items: Vec::new(),
        edits: Vec::new(),
        extent: None,
        views: None,
        views_at: None,
        lighting: None,
        units_per_metre: None,
        limits: *limits,
    };
    let mut loader = Loader { limits, stack: Vec::new(), loads: 0, parsed: HashMap::new() };
    loader.load_into(&mut loaded, path, Some(text.to_string()), None, false)?;
    Ok(loaded)
}

fn canonical(p: &Path) -> PathBuf {
    std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf())
}

/// One file, parsed, located and validated: what every later load of the same file reuses.
#[derive(Debug, Clone)]
struct ParsedFile {
    /// Index of the file in [`LoadedScript::files`].
    file: usize,
    /// The script without its assets, layout and edits (they are below, located).
    script: Script,
    items: Vec<ItemNode>,
    edits: Vec<EditNode>,
    assets: Vec<(String, AssetEntry)>,
    views_at: Option<Location>,
}

/// The state of one [`load_str_with`]: the chain of files being read (for cycles and the
/// depth limit), the loads so far, and every file already parsed, by canonical path.
struct Loader<'a> {
    limits: &'a Limits,
    stack: Vec<PathBuf>,
    loads: usize,
    parsed: HashMap<PathBuf, ParsedFile>,
}

impl Loader<'_> {
    /// Check the depth and load limits for one more file, named at `from` (the main file
    /// when `None`).
    fn admit(&mut self, path: &Path, from: Option<&Location>) -> Result<(), LayoutError> {
        let here = || {
            from.cloned().unwrap_or_else(|| Location { file: path.to_path_buf(), line: 1, col: 1 })
        };
        let depth = self.stack.len().saturating_add(1);
        if depth > self.limits.max_include_depth {
            return Err(self.limits.exceeded(
                Limit::IncludeDepth,
                &here(),
                format!("{} would be read at nesting level {depth}", path.display()),
            ));
        }
        self.loads = self.loads.saturating_add(1);
        if self.loads > self.limits.max_file_loads {
            return Err(self.limits.exceeded(
                Limit::FileLoads,
                &here(),
                format!("{} would be file load number {}", path.display(), self.loads),
            ));
        }
        Ok(())
    }

    fn load_into(
        &mut self,
        out: &mut LoadedScript,
        path: &Path,
        text: Option<String>,
        from: Option<&Location>,
        assets_only: bool,
    ) -> Result<(), LayoutError> {
        let key = canonical(path);
        if self.stack.contains(&key) {
            let cycle =
                self.stack.iter().chain(std::iter::once(&key)).map(|p| p.display().to_string());
            return Err(LayoutError::Cycle {
                path: path.to_path_buf(),
                cycle: cycle.collect::<Vec<_>>().join(" -> "),
            });
        }
        self.admit(path, from)?;
        // asset files are parsed once, however often they are included (the main file,
        // given as text, need not be what is on disk)
        let cached = if assets_only { self.parsed.get(&key).cloned() } else { None };
        let parsed = match cached {
            Some(p) => p,
            None => {
                let text = match text {
                    Some(t) => t,
                    None => read_script_file(path, self.limits, from)?,
                };
                let p = parse_file(out, path, text)?;
                if assets_only {
                    self.parsed.insert(key.clone(), p.clone());
                }
                p
            }
        };
        let file = parsed.file;
        let script = &parsed.script;
        if assets_only
            && (!parsed.items.is_empty() || !parsed.edits.is_empty() || script.base.is_some())
        {
            return Err(LayoutError::Semantic {
                location: out.files[file].location(0),
                message: "an included file may only define assets (use `base` to extend a scene)"
                    .into(),
            });
        }
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        self.stack.push(key);
        if let Some(base) = &script.base {
            let at = out.files[file].find_string(base);
            self.load_into(out, &dir.join(base), None, at.as_ref(), false)?;
        }
        for inc in &script.include {
            let inc_path = dir.join(inc);
            let src = &out.files[file];
            let location = src.find_string(inc).unwrap_or_else(|| src.location(0));
            if !inc_path.exists() {
                return Err(LayoutError::Semantic {
                    location,
                    message: format!("included file {} does not exist", inc_path.display()),
                });
            }
            self.load_into(out, &inc_path, None, Some(&location), true)?;
        }
        self.stack.pop();

        let ParsedFile { script, items, edits, assets, views_at, .. } = parsed;
        out.assets.extend(assets);
        if !assets_only {
            if let Some(n) = script.name {
                out.name = n;
            }
            out.extent = script.extent.or(out.extent);
            if script.views.is_some() {
                out.views = script.views;
                out.views_at = views_at;
            }
            out.lighting = script.lighting.or(out.lighting.take());
            out.units_per_metre = script.units_per_metre.or(out.units_per_metre);
            out.items.extend(items);
            out.edits.extend(edits);
        }
        Ok(())
    }
}

/// Parse one file into `out.files`, locate its assets, items and edits, and validate every
/// number it gives.
fn parse_file(
    out: &mut LoadedScript,
    path: &Path,
    text: String,
) -> Result<ParsedFile, LayoutError> {
    let mut script = parse_script(path, &text)?;
    let file = out.files.len();
    out.files.push(SourceFile::new(path.to_path_buf(), text));
    let src = &out.files[file];
    let assets: Vec<(String, AssetEntry)> = std::mem::take(&mut script.assets)
        .into_iter()
        .map(|(name, def)| {
            let location = src.find_string(&name).unwrap_or_else(|| src.location(0));
            (name.clone(), AssetEntry { def, file, location })
        })
        .collect();
    let mut counters: HashMap<&'static str, usize> = HashMap::new();
    let items: Vec<ItemNode> = std::mem::take(&mut script.layout)
        .into_iter()
        .map(|item| locate_item(src, file, item, &mut counters))
        .collect();
    let edits = locate_edits(src, file, std::mem::take(&mut script.edits), &mut counters);
    let views_at = script.views.as_ref().map(|_| src.find_ident("views", 0));
    for (name, entry) in &assets {
        validate::asset(name, &entry.def, &entry.location)?;
    }
    validate::items(&items)?;
    validate::edits(&edits)?;
    validate::settings(&script, src)?;
    Ok(ParsedFile { file, script, items, edits, assets, views_at })
}

/// Locate edits: the k-th edit of a variant is the k-th occurrence of its identifier after
/// the layout items (which `counters` has counted).
fn locate_edits(
    src: &SourceFile,
    file: usize,
    edits: Vec<Edit>,
    counters: &mut HashMap<&'static str, usize>,
) -> Vec<EditNode> {
    edits
        .into_iter()
        .map(|edit| {
            let n = counters.entry(edit.variant()).or_default();
            let offset = src.ident_offset(edit.variant(), *n);
            *n += 1;
            EditNode { edit, location: src.location(offset), offset, file }
        })
        .collect()
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
    let offset = src.ident_offset(item.variant(), *n);
    *n += 1;
    let children = match &item {
        Item::Group { children, .. } => {
            children.iter().cloned().map(|c| locate_item(src, file, c, counters)).collect()
        }
        _ => Vec::new(),
    };
    ItemNode { item, location: src.location(offset), offset, file, children }
}

/// Append the `edits` of the script at `path` to `script` (after its own edits), ignoring
/// that file's `base`: the same edit list can then be applied to another layout of the same
/// scene (e.g. one written against the ground-truth scene, applied to a mined layout whose
/// instances carry the ground-truth keys). The file may hold edits only; it is read under
/// the script's [`LoadedScript::limits`]. Returns how many edits were added.
pub fn append_edits(script: &mut LoadedScript, path: &Path) -> Result<usize, LayoutError> {
    let text = read_script_file(path, &script.limits, None)?;
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
    let edits = locate_edits(src, file, parsed.edits, &mut HashMap::new());
    validate::edits(&edits)?;
    let n = edits.len();
    script.edits.extend(edits);
    Ok(n)
}

/// Append edits given as text to `script` (after its edits): a bare edit list
/// (`[Move(target: "obj3", by: (0.5, 0.0)), ...]`) or a script holding `edits` only (its `base`
/// ignored, as [`append_edits`] does). `name` names the text in messages (`name:line:col`).
/// On error the script is unchanged. Returns how many edits were added.
pub fn append_edits_str(
    script: &mut LoadedScript,
    name: &Path,
    text: &str,
) -> Result<usize, LayoutError> {
    let size = u64::try_from(text.len()).unwrap_or(u64::MAX);
    if size > script.limits.max_file_bytes {
        return Err(LayoutError::TooLarge {
            path: name.to_path_buf(),
            size,
            limit: script.limits.max_file_bytes,
            referenced_at: None,
        });
    }
    let src = SourceFile::new(name.to_path_buf(), text.to_string());
    let first = strip_comments_and_space(text);
    let edits = if first.starts_with('[') {
        ron_options().from_str::<Vec<Edit>>(text).map_err(|e| LayoutError::Syntax {
            location: Location {
                file: name.to_path_buf(),
                line: e.span.start.line,
                col: e.span.start.col,
            },
            message: e.code.to_string(),
        })?
    } else {
        let parsed = parse_script(name, text)?;
        if !parsed.layout.is_empty() || !parsed.assets.is_empty() || !parsed.include.is_empty() {
            return Err(LayoutError::Semantic {
                location: src.location(0),
                message: "an edit list may only hold edits: write `[Move(...), ...]` or `Scene(edits: [...])`"
                    .into(),
            });
        }
        parsed.edits
    };
    let file = script.files.len();
    let located = locate_edits(&src, file, edits, &mut HashMap::new());
    validate::edits(&located)?;
    let n = located.len();
    script.files.push(src);
    script.edits.extend(located);
    Ok(n)
}

/// `text` after leading whitespace and `//` or `/* */` comments (and a `#![...]` attribute).
fn strip_comments_and_space(mut text: &str) -> &str {
    loop {
        let t = text.trim_start();
        if let Some(rest) = t.strip_prefix("//") {
            text = rest.split_once('\n').map_or("", |(_, r)| r);
        } else if let Some(rest) = t.strip_prefix("/*") {
            text = rest.split_once("*/").map_or("", |(_, r)| r);
        } else if let Some(rest) = t.strip_prefix("#![") {
            text = rest.split_once(']').map_or("", |(_, r)| r);
        } else {
            return t;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edits_from_text_are_located_in_the_text_and_a_bad_one_changes_nothing() {
        let scene = "Scene(\n  assets: {\n    \"a\": Asset(parts: [Box(center: (0, 0, 0.5), size: (1, 1, 1), color: (1, 0, 0))]),\n  },\n  layout: [\n    Row(asset: \"a\", from: (0, 0), to: (4, 0), count: 3, name: \"r\"),\n  ],\n)\n";
        let mut script = load_str(Path::new("s.ron"), scene).unwrap();
        let req = Path::new("request");
        let n = append_edits_str(
            &mut script,
            req,
            "// a move\n[\n  Move(target: \"r[0]\", by: (1, 0)),\n  Remove(\"r[1]\"),\n]",
        )
        .unwrap();
        assert_eq!(n, 2);
        assert_eq!(script.edits[0].location.to_string(), "request:3:3");
        let n =
            append_edits_str(&mut script, req, "Scene(edits: [Rotate(target: \"r[2]\", by: 90)])")
                .unwrap();
        assert_eq!(n, 1);
        let before = script.edits.len();
        let e = append_edits_str(
            &mut script,
            req,
            "[\n  Move(target: \"r[0]\", by: (1, 0),\n  Nonsense(1),\n]",
        )
        .unwrap_err();
        let at = e.location().expect("a syntax error has a place");
        assert_eq!((at.file.as_path(), at.line), (req, 3), "{e}");
        assert_eq!(script.edits.len(), before, "nothing added");
        let e = append_edits_str(
            &mut script,
            req,
            "Scene(layout: [Instance(asset: \"a\", at: (0, 0))])",
        )
        .unwrap_err();
        assert!(e.to_string().starts_with("request:1:1"), "{e}");
        assert_eq!(script.edits.len(), before);
        let catalog = crate::PartsCatalog::from_script(&script);
        let layout = crate::resolve(&script, &catalog).unwrap();
        let keys: Vec<&str> = layout.instances.iter().map(|i| i.key.as_str()).collect();
        assert_eq!(keys, ["r[0]", "r[2]"]);
        // Add places a new instance on the ground, keyed after its asset unless named
        let text =
            "[Add(asset: \"a\", at: (1, 2), yaw: 30), Add(asset: \"a\", at: (3, 2), name: \"n\")]";
        append_edits_str(&mut script, req, text).unwrap();
        let layout = crate::resolve(&script, &catalog).unwrap();
        let added = layout.instances.iter().find(|i| i.key == "a+new1").expect("a+new1");
        assert_eq!(added.transform.position, glam::Vec2::new(1.0, 2.0));
        assert_eq!((added.transform.yaw_deg, added.transform.scale), (30.0, 1.0));
        assert!(layout.instances.iter().any(|i| i.key == "n"));
        // a key that exists is refused, naming the edit
        append_edits_str(&mut script, req, "[Add(asset: \"a\", at: (0, 0), name: \"n\")]").unwrap();
        let e = crate::resolve(&script, &catalog).unwrap_err().to_string();
        assert!(e.contains("request:1:2") && e.contains("exists already"), "{e}");
    }

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
