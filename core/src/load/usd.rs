//! USD (`.usda` text, `.usdc` binary, `.usd` either) into a `BaseMesh`, read with the `openusd`
//! crate (0.6, pure Rust; it composes sublayers and references into a stage).
//!
//! Every defined, active `Mesh` prim (purpose not `guide`) is appended with its world transform
//! (every `xformOp` of the prim and its ancestors, `!resetXformStack!` and `!invert!` honoured):
//! polygons fan-triangulated, `leftHanded` orientation flipped to counter-clockwise, normals
//! (`primvars:normals` over `normals`) and the UV primvar expanded from any interpolation and
//! optional `:indices` to one value per face corner, then corners with equal (point, normal, UV)
//! shared. USD's `st` has v pointing up like the project: no flip. Stage `upAxis` becomes
//! `mesh.up_axis`.
//!
//! `displacement` reads the bound `UsdPreviewSurface`'s `inputs:displacement` ← `UsdUVTexture`
//! and turns USD's `D = scale·h + bias` into the project's `D = S·(h − M)`: `S = scale`,
//! `M = −bias / scale` (per DESIGN.md, `bias = −M·S`).
//!
//! Departures from USD, on purpose: subdivision schemes are ignored (the cage is the mesh),
//! instancing is not expanded (GeomSubset material bindings are read for the beauty, a
//! displacement per subset is not), time-sampled values are read
//! at their first sample, `elementSize` > 1 is refused.

use super::MeshOptions;
use crate::error::{Error, Result};
use crate::heightmap::Wrap;
use crate::mesh::{
    AlphaMode, BaseMesh, MeshMaterial, Projection, SceneDome, SceneSun, UpAxis, MAX_MATERIALS,
};
use crate::render::lights::{Light, LightShape, Spot};
use crate::texture::{
    ChannelRef, ColorSpace, NormalMapRef, Sampler, TexWrap, TextureData, TextureRef, UvTransform,
};
use glam::{DMat4, DQuat, DVec3, Mat3, Vec2, Vec3};
use openusd::sdf::{self, Value};
use openusd::usd::{Prim, Stage};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The displacement a USD material carries, in the project's convention.
#[derive(Clone, Debug, PartialEq)]
pub struct UsdDisplacement {
    /// The texture (`inputs:file`), resolved against the layer that authored it.
    pub file: PathBuf,
    /// `S` in `D = S·(h − M)`: the texture's `inputs:scale` of the channel used.
    pub scale: f32,
    /// `M = −bias / scale`.
    pub midlevel: f32,
    pub wrap: Wrap,
    /// The texture output the displacement reads: `R`, `G`, `B` or `A`.
    pub channel: String,
    /// The primvar the texture's `st` reader names (`inputs:varname`), usually `st`.
    pub uv_primvar: Option<String>,
}

/// Load every mesh of the stage.
pub fn load(path: &Path, opts: &MeshOptions) -> Result<BaseMesh> {
    guarded(path, || {
        let stage = open(path)?;
        let mut loader = Loader {
            path,
            opts,
            stage: &stage,
            mesh: BaseMesh {
                source: path.into(),
                up_axis: Some(up_axis(&stage)),
                ..Default::default()
            },
            any_uv_missing: false,
            material_paths: vec![],
            cameras: vec![],
            unread_lights: vec![],
        };
        let root = stage.prim(sdf::Path::abs_root());
        for child in children(path, &root)? {
            loader.visit(&child, DMat4::IDENTITY, 1)?;
        }
        if !loader.unread_lights.is_empty() {
            let n = loader.unread_lights.len();
            warn(
                path,
                &format!(
                    "{n} light{} not read: {} (the beauty renders dome, distant, sphere, rect \
                     and disk lights; cylinder, mesh, portal and plugin lights are not rendered)",
                    if n == 1 { " is" } else { "s are" },
                    loader.unread_lights.join(", ")
                ),
            );
        }
        let mut mesh = loader.mesh;
        mesh.missing_uvs = loader.any_uv_missing;
        mesh.face_flags = vec![0; mesh.triangles.len()];
        for (names, world, projection, film_aspect) in loader.cameras {
            super::attach_camera(
                &mut mesh,
                names,
                world.as_mat4(),
                projection,
                film_aspect,
                false,
            );
        }
        Ok(mesh)
    })
}

/// The displacement of the first mesh whose bound material has one (a warning when later
/// meshes disagree); `None` when no mesh has a texture-driven displacement.
pub fn displacement(path: &Path) -> Result<Option<UsdDisplacement>> {
    guarded(path, || {
        let stage = open(path)?;
        let mut meshes = Vec::new();
        collect_meshes(path, &stage.prim(sdf::Path::abs_root()), 0, &mut meshes)?;
        let mut found: Option<UsdDisplacement> = None;
        for prim in &meshes {
            let Some(d) = mesh_displacement(path, &stage, prim)? else {
                continue;
            };
            match &found {
                None => found = Some(d),
                Some(first) if *first != d => warn(
                    path,
                    &format!(
                        "{} has a different displacement than the first mesh; the first is used",
                        prim.path()
                    ),
                ),
                Some(_) => {}
            }
        }
        Ok(found)
    })
}

/// openusd may panic on some corrupt inputs: turn that into an error naming the file. The
/// panic is expected here, so it prints nothing (`super::catch_quietly`): the user sees the
/// error only.
fn guarded<T>(path: &Path, f: impl FnOnce() -> Result<T>) -> Result<T> {
    super::catch_quietly(f).unwrap_or_else(|| {
        Err(Error::invalid(
            path,
            "the USD reader (openusd 0.6) crashed on this file: it is corrupt or uses a feature \
             the reader lacks (re-export it, or convert it with `usdcat -o file.usda`)",
        ))
    })
}

/// Deepest `{`, `(` or `[` nesting accepted in a text layer. openusd's text parser and its
/// composition recurse once per level, so a hostile file nested thousands deep overflows the
/// stack (an abort no `catch_unwind` can turn into an error); real layers nest a few dozen.
pub const MAX_USDA_NESTING: usize = 100;

/// Square brackets inside square brackets a text layer may nest: USD's arrays and list ops
/// do not nest, and openusd 0.6 parses a metadata value of nested `[` by trying its
/// alternatives at every level, twice the time and memory for each level past about 20 (a
/// 174-byte layer, `dices = [[[…` 57 deep, held 24 GB for 3 minutes).
pub const MAX_USDA_ARRAY_NESTING: usize = 8;

/// The identifier-like word at `i` (letters, digits, `_`, `:`), advancing past it.
fn take_word<'b>(bytes: &'b [u8], i: &mut usize) -> &'b [u8] {
    let start = *i;
    while *i < bytes.len()
        && (bytes[*i].is_ascii_alphanumeric() || matches!(bytes[*i], b'_' | b':'))
    {
        *i += 1;
    }
    &bytes[start..*i]
}

/// A USD identifier: letters, digits and `_`, not starting with a digit (UTF-8 letters
/// allowed). Prim names must be one; property names are identifiers joined by `:`.
fn is_identifier(s: &str) -> bool {
    s.chars()
        .next()
        .is_some_and(|c| c.is_alphabetic() || c == '_')
        && s.chars().all(|c| c.is_alphanumeric() || c == '_')
}

/// A relationship target or connection `target` of property `at`, if it is a path the reader
/// can follow: prim names that are identifiers from the root (with variant selections), then
/// at most a property name (identifiers joined by `:`). A mangled one (`/root/…/Mappinp/*hh…`, spaces, `*` and NULs
/// in it: the text parser and the pre-check disagreed on where a string ended) sent openusd's
/// instancing into endless recursion when its prim was asked for (found by fuzzing).
fn checked_target(path: &Path, at: &sdf::Path, target: sdf::Path) -> Result<sdf::Path> {
    let text = target.as_str();
    let (prim, prop) = match text.rsplit_once('/') {
        Some((head, last)) => match last.split_once('.') {
            Some((name, prop)) => (format!("{head}/{name}"), Some(prop)),
            None => (text.to_string(), None),
        },
        None => (text.to_string(), None),
    };
    // A prim name, then any variant selections `{set=name}`.
    let component = |c: &str| {
        let (name, mut rest) = c.split_once('{').map_or((c, ""), |(n, r)| (n, r));
        if !is_identifier(name) {
            return false;
        }
        while !rest.is_empty() {
            let Some((sel, after)) = rest.split_once('}') else {
                return false;
            };
            let Some((set, choice)) = sel.split_once('=') else {
                return false;
            };
            if !is_identifier(set) || !(choice.is_empty() || is_identifier(choice)) {
                return false;
            }
            rest = after.strip_prefix('{').unwrap_or(after);
            if !after.is_empty() && !after.starts_with('{') {
                return false;
            }
        }
        true
    };
    let prim_ok = prim
        .strip_prefix('/')
        .is_some_and(|p| p.split('/').all(component));
    let prop_ok = prop.is_none_or(|p| p.split(':').all(is_identifier));
    if prim_ok && prop_ok {
        return Ok(target);
    }
    let shown: String = text.chars().take(80).collect();
    Err(prim_err(
        path,
        at,
        format!(
            "targets \"{}\", which is not a path of prim names (letters, digits and _) and a \
             property name; the file is corrupt (re-export it)",
            shown.escape_debug()
        ),
    ))
}

/// Whether `p` (between a path's `<` and `>`) is made of path characters only: identifier
/// characters, `/ . : -`, variant selections `{set=name}` (not nested), and balanced
/// `[ ]` around target paths. A stray `}` (`</…/Image_Text}re.outputs:rgb>`, found by
/// fuzzing) sent openusd's instancing into endless recursion, as a path running past its
/// line did.
fn is_path_text(p: &[u8]) -> bool {
    let (mut squares, mut brace) = (0usize, false);
    for &c in p {
        match c {
            b'{' if !brace => brace = true,
            b'}' if brace => brace = false,
            b'[' => squares += 1,
            b']' if squares > 0 => squares -= 1,
            b'=' if brace => {}
            b'_' | b'/' | b'.' | b':' | b'-' => {}
            c if c.is_ascii_alphanumeric() || c >= 0x80 => {}
            _ => return false,
        }
    }
    !brace && squares == 0
}

/// After `def` / `over` / `class` at `i`: skip an optional type name; a quoted prim name must
/// be an identifier (letters, digits and `_`, not starting with a digit; UTF-8 letters allowed).
fn check_prim_name(path: &Path, bytes: &[u8], i: &mut usize, line: usize) -> Result<()> {
    let skip_blanks = |i: &mut usize| {
        while *i < bytes.len() && matches!(bytes[*i], b' ' | b'\t') {
            *i += 1;
        }
    };
    skip_blanks(i);
    if *i < bytes.len() && bytes[*i].is_ascii_alphabetic() {
        take_word(bytes, i);
        skip_blanks(i);
    }
    if *i >= bytes.len() || bytes[*i] != b'"' {
        return Ok(());
    }
    // A quoted name ends on its line: openusd reads one that runs on (with `/` or `}` in
    // it) as path syntax and recursed without end, or looped for minutes.
    let len = bytes[*i + 1..]
        .iter()
        .position(|&b| b == b'"' || b == b'\n')
        .filter(|&len| bytes[*i + 1 + len] == b'"')
        .ok_or_else(|| {
            Error::invalid(
                path,
                format!(
                    "line {line}: a prim name's quotes are not closed on its line; the file is \
                     corrupt (re-export it)"
                ),
            )
        })?;
    let name = String::from_utf8_lossy(&bytes[*i + 1..*i + 1 + len]);
    if !is_identifier(&name) {
        return Err(Error::invalid(
            path,
            format!(
                "line {line}: prim name \"{name}\" is not a USD identifier (letters, digits and \
                 _, not starting with a digit); the file is corrupt, or rename the prim"
            ),
        ));
    }
    Ok(())
}

/// Refuse a text layer nested deeper than `MAX_USDA_NESTING` (strings and comments skipped),
/// with square brackets nested deeper than `MAX_USDA_ARRAY_NESTING`, with a prim whose name
/// is not an identifier or whose quotes do not close on its line, or with a path `<…>` that
/// does not close on its line or holds what no path does.
/// Binary layers (`PXR-USDC`) are not scanned.
fn check_nesting(path: &Path) -> Result<()> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    if bytes.starts_with(b"PXR-USDC") {
        return super::usdc_check::check(path, &bytes);
    }
    let (mut deepest, mut line, mut deepest_line) = (0usize, 1usize, 1usize);
    // Open brackets, innermost last: how deep the text is nested, what a closing bracket
    // closes, and so how many `[` are open inside one another.
    let mut open: Vec<u8> = Vec::new();
    let mut squares = 0usize;
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            b'\n' => line += 1,
            // Comments as openusd's lexer skips them: `#` to the end of the line, which a
            // carriage return ends too (a `[[[…` after `#…\r` was hidden from this scan and
            // not from the parser: found by fuzzing), and `/* … */`.
            b'#' => {
                while i < bytes.len() && !matches!(bytes[i], b'\n' | b'\r') {
                    i += 1;
                }
                continue;
            }
            b'/' if bytes.get(i + 1) == Some(&b'*') => {
                let end = bytes[i + 2..]
                    .windows(2)
                    .position(|w| w == b"*/")
                    .map_or(bytes.len(), |k| i + 2 + k + 2);
                line += bytes[i..end].iter().filter(|&&b| b == b'\n').count();
                i = end;
                continue;
            }
            q @ (b'"' | b'\'') => {
                // A string, single or triple quoted; backslash escapes the next byte. A single
                // quoted one must close on its line (no valid one holds a newline; openusd's
                // lexer would read on to the next quote, so where this scan and the parser
                // resume would differ, and brackets or a path one sees could hide from the
                // other: found by fuzzing).
                let triple = bytes[i..].starts_with(&[q, q, q]);
                i += if triple { 3 } else { 1 };
                loop {
                    match bytes.get(i) {
                        Some(b'\\') => i += 2,
                        Some(b'\n') if !triple => {
                            return Err(Error::invalid(
                                path,
                                format!(
                                    "line {line}: a string's quotes are not closed on its line; \
                                     the file is corrupt (re-export it)"
                                ),
                            ))
                        }
                        Some(&b) if b == q && (!triple || bytes[i..].starts_with(&[q, q, q])) => {
                            i += if triple { 3 } else { 1 };
                            break;
                        }
                        Some(&b) => {
                            line += (b == b'\n') as usize;
                            i += 1;
                        }
                        None => break,
                    }
                }
                continue;
            }
            c if c.is_ascii_alphabetic() => {
                // A word: after `def`, `over` or `class` (and an optional type name) comes the
                // prim's name, which must be an identifier; openusd takes `{`, `}` and the like
                // in a name for path syntax and recurses without end.
                let word = take_word(&bytes, &mut i);
                if matches!(word, b"def" | b"over" | b"class") {
                    check_prim_name(path, &bytes, &mut i, line)?;
                }
                continue;
            }
            b'<' => {
                // A path `<…>` closes on its line and holds path characters only: openusd took
                // a relationship target that ran on (`</rooint3f[] points = [(-1, …` over a
                // dozen lines) for path syntax and recursed without end (a stack overflow).
                let start = i + 1;
                let end = bytes[start..]
                    .iter()
                    .position(|&b| b == b'>' || b == b'\n')
                    .map(|k| start + k)
                    .filter(|&e| bytes[e] == b'>');
                let bad = match end {
                    None => Some("its angle brackets are not closed on its line"),
                    Some(e) => (!is_path_text(&bytes[start..e]))
                        .then_some("it holds characters no path has, or unbalanced { } [ ]"),
                };
                if let Some(why) = bad {
                    return Err(Error::invalid(
                        path,
                        format!(
                            "line {line}: a path (`<…>`): {why}; the file is corrupt (re-export it)"
                        ),
                    ));
                }
                i = end.unwrap_or(i) + 1;
                continue;
            }
            b @ (b'{' | b'(' | b'[') => {
                open.push(b);
                if open.len() > deepest {
                    (deepest, deepest_line) = (open.len(), line);
                }
                if b == b'[' {
                    squares += 1;
                    if squares > MAX_USDA_ARRAY_NESTING {
                        return Err(Error::invalid(
                            path,
                            format!(
                                "line {line}: square brackets nested more than \
                                 {MAX_USDA_ARRAY_NESTING} deep; USD arrays do not nest, so the \
                                 file is corrupt (re-export it)"
                            ),
                        ));
                    }
                }
            }
            b'}' | b')' | b']' => squares -= (open.pop() == Some(b'[')) as usize,
            _ => {}
        }
        i += 1;
    }
    if deepest > MAX_USDA_NESTING {
        return Err(Error::invalid(
            path,
            format!(
                "nests brackets {deepest} levels deep (line {deepest_line}); the USD reader \
                 accepts at most {MAX_USDA_NESTING} (the file is corrupt, or flatten its \
                 hierarchy, e.g. with `usdcat --flatten`)"
            ),
        ));
    }
    Ok(())
}

fn open(path: &Path) -> Result<Stage> {
    check_nesting(path)?;
    let s = path
        .to_str()
        .ok_or_else(|| Error::invalid(path, "the path is not UTF-8 (rename the file)"))?;
    Stage::open(s).map_err(|e| {
        Error::invalid(
            path,
            format!(
                "cannot be read as USD: {e:#} (the file is truncated or corrupt, or uses a feature \
                 openusd 0.6 lacks; re-export it, or convert it with `usdcat -o file.usda`)"
            ),
        )
    })
}

fn warn(path: &Path, what: &str) {
    eprintln!("warning: {}: {what}", path.display());
}

/// An error about one prim (or property) of the file, with what to do.
fn prim_err(path: &Path, at: &sdf::Path, what: impl std::fmt::Display) -> Error {
    Error::invalid(path, format!("{at}: {what}"))
}

fn usd_err(path: &Path, at: &sdf::Path, e: impl std::fmt::Display) -> Error {
    prim_err(
        path,
        at,
        format!("cannot be read: {e:#} (re-export the file)"),
    )
}

fn up_axis(stage: &Stage) -> UpAxis {
    match stage.stage_metadata("upAxis").ok().flatten() {
        Some(v) if v.as_str() == Some("Z") => UpAxis::Z,
        _ => UpAxis::Y,
    }
}

/// The children of `prim`, each named by a USD identifier (letters, digits and `_`, not
/// starting with a digit). A binary layer's prim names are tokens from the file, not parsed:
/// a fuzzed name with path syntax in it sent openusd's instancing into endless recursion
/// (`is_active` on the child, a stack overflow), as text layers' names did before
/// `check_prim_name`.
fn children(path: &Path, prim: &Prim) -> Result<Vec<Prim>> {
    let kids = prim.children().map_err(|e| usd_err(path, prim.path(), e))?;
    let parent = prim.path().as_str();
    for kid in &kids {
        let full = kid.path().as_str();
        // Exactly the parent's path, `/` and a name: a corrupt binary layer can state a
        // child path with more levels in it ("/spuiA}/ad" under the root), on which openusd's
        // instancing queries recurse without end.
        let name = full
            .strip_prefix(parent)
            .and_then(|rest| match parent {
                "/" => Some(rest),
                _ => rest.strip_prefix('/'),
            })
            .unwrap_or(full);
        if !is_identifier(name) {
            let shown: String = full.chars().take(80).collect();
            return Err(prim_err(
                path,
                prim.path(),
                format!(
                    "has a child prim \"{}\" whose name is not a USD identifier (letters, digits \
                     and _, not starting with a digit); the file is corrupt (re-export it)",
                    shown.escape_debug()
                ),
            ));
        }
    }
    Ok(kids)
}

/// A mesh's material subsets (`Loader::material_subsets`): each one's (path, material), and
/// per face the number of its subset from 1 (0: none, the mesh's own material).
type SubsetBinding = (Vec<(String, u32)>, Vec<u32>);

fn type_name(prim: &Prim) -> String {
    prim.type_name()
        .ok()
        .flatten()
        .map(|t| t.as_str().to_string())
        .unwrap_or_default()
}

/// Defined, active, not a class, and not a guide: a prim that renders.
fn is_renderable(path: &Path, prim: &Prim) -> Result<bool> {
    let e = |e| usd_err(path, prim.path(), e);
    if !prim.is_active().map_err(e)?
        || !prim.is_defined().map_err(e)?
        || prim.is_abstract().map_err(e)?
    {
        return Ok(false);
    }
    let purpose = value(path, prim, "purpose")?;
    Ok(purpose.as_ref().and_then(|v| v.as_str()) != Some("guide"))
}

/// Deepest prim hierarchy the loader walks. Both walks (`collect_meshes`, `Loader::visit`)
/// recurse once per level; a fuzzed binary layer whose composed children never end
/// (`/quad/quad/quad/…`) overflowed the stack 23 000 levels down. Real assets nest a few
/// dozen levels.
pub const MAX_PRIM_DEPTH: usize = 256;

/// `Err` naming the prim when it lies deeper than `MAX_PRIM_DEPTH` (`depth`: its level).
fn check_depth(path: &Path, prim: &Prim, depth: usize) -> Result<()> {
    if depth <= MAX_PRIM_DEPTH {
        return Ok(());
    }
    let full = prim.path().as_str();
    let shown: String = full.chars().take(80).collect();
    let more = if shown.len() < full.len() { "…" } else { "" };
    Err(Error::invalid(
        path,
        format!(
            "prims nest more than {MAX_PRIM_DEPTH} levels deep (at {shown}{more}); the file is \
             corrupt, or its hierarchy loops (flatten it, e.g. with `usdcat --flatten`)"
        ),
    ))
}

fn collect_meshes(path: &Path, prim: &Prim, depth: usize, out: &mut Vec<Prim>) -> Result<()> {
    for child in children(path, prim)? {
        check_depth(path, &child, depth + 1)?;
        if !is_renderable(path, &child)? {
            continue;
        }
        if type_name(&child) == "Mesh" {
            out.push(child.clone());
        }
        collect_meshes(path, &child, depth + 1, out)?;
    }
    Ok(())
}

/// The composed value of an attribute: its default, else its first time sample.
fn attr_value(path: &Path, stage: &Stage, attr_path: &sdf::Path) -> Result<Option<Value>> {
    let attr = stage.attribute(attr_path.clone());
    let e = |e| usd_err(path, attr_path, e);
    match attr.get::<Value>().map_err(e)? {
        Some(Value::ValueBlock) => return Ok(None),
        Some(v) => return Ok(Some(v)),
        None => {}
    }
    let times = attr.time_sample_times().map_err(e)?;
    match times.first() {
        Some(&t) => Ok(attr
            .get_at::<Value>(openusd::usd::TimeCode::from(t))
            .map_err(e)?),
        None => Ok(None),
    }
}

fn value(path: &Path, prim: &Prim, name: &str) -> Result<Option<Value>> {
    let p = property_path(path, prim.path(), name)?;
    attr_value(path, prim.stage(), &p)
}

/// The path of property `name` of `prim`. The name must be a namespaced identifier (letters,
/// digits and `_` per namespace, not starting with a digit, namespaces joined by `:`): names
/// come from the file too (`xformOpOrder`'s tokens), and a fuzzed one with path syntax in it
/// (`"xformOp:translaunts0, 0), (~/quad.primvars…"`) sent openusd's instancing into endless
/// recursion (a stack overflow, an abort).
fn property_path(path: &Path, prim: &sdf::Path, name: &str) -> Result<sdf::Path> {
    if !name.split(':').all(is_identifier) {
        let shown: String = name.chars().take(60).collect();
        let more = if shown.len() < name.len() { "…" } else { "" };
        return Err(prim_err(
            path,
            prim,
            format!(
                "property name \"{}{more}\" is not a USD identifier (letters, digits and _ per \
                 namespace, namespaces joined by ':'); the file is corrupt (re-export it)",
                shown.escape_debug()
            ),
        ));
    }
    prim.append_property(name)
        .map_err(|e| prim_err(path, prim, format!("invalid property name '{name}': {e:#}")))
}

fn metadata_token(stage: &Stage, attr: &sdf::Path, key: &str) -> Option<String> {
    let v: Value = stage
        .attribute(attr.clone())
        .get_metadata(key)
        .ok()
        .flatten()?;
    v.as_str().map(str::to_string)
}

// ---- value conversion: USD authors the same data as float, double or half ----

fn scalar(v: &Value) -> Option<f64> {
    Some(match v {
        Value::Float(x) => *x as f64,
        Value::Double(x) => *x,
        Value::Half(x) => x.to_f64(),
        Value::Int(x) => *x as f64,
        _ => return None,
    })
}

fn vec3(v: &Value) -> Option<DVec3> {
    Some(match v {
        Value::Vec3f(a) => DVec3::new(a.x as f64, a.y as f64, a.z as f64),
        Value::Vec3d(a) => DVec3::new(a.x, a.y, a.z),
        Value::Vec3h(a) => DVec3::new(a.x.to_f64(), a.y.to_f64(), a.z.to_f64()),
        _ => return None,
    })
}

fn vec2(v: &Value) -> Option<[f32; 2]> {
    Some(match v {
        Value::Vec2f(a) => [a.x, a.y],
        Value::Vec2d(a) => [a.x as f32, a.y as f32],
        Value::Vec2h(a) => [a.x.to_f32(), a.y.to_f32()],
        _ => return None,
    })
}

fn vec4(v: &Value) -> Option<[f64; 4]> {
    Some(match v {
        Value::Vec4f(a) => [a.x as f64, a.y as f64, a.z as f64, a.w as f64],
        Value::Vec4d(a) => [a.x, a.y, a.z, a.w],
        Value::Vec4h(a) => [a.x.to_f64(), a.y.to_f64(), a.z.to_f64(), a.w.to_f64()],
        _ => return None,
    })
}

fn vec3_array(v: &Value) -> Option<Vec<Vec3>> {
    Some(match v {
        Value::Vec3fVec(a) => a.iter().map(|p| Vec3::new(p.x, p.y, p.z)).collect(),
        Value::Vec3dVec(a) => a
            .iter()
            .map(|p| Vec3::new(p.x as f32, p.y as f32, p.z as f32))
            .collect(),
        Value::Vec3hVec(a) => a
            .iter()
            .map(|p| Vec3::new(p.x.to_f32(), p.y.to_f32(), p.z.to_f32()))
            .collect(),
        _ => return None,
    })
}

fn vec2_array(v: &Value) -> Option<Vec<Vec2>> {
    Some(match v {
        Value::Vec2fVec(a) => a.iter().map(|p| Vec2::new(p.x, p.y)).collect(),
        Value::Vec2dVec(a) => a
            .iter()
            .map(|p| Vec2::new(p.x as f32, p.y as f32))
            .collect(),
        Value::Vec2hVec(a) => a
            .iter()
            .map(|p| Vec2::new(p.x.to_f32(), p.y.to_f32()))
            .collect(),
        _ => return None,
    })
}

fn int_array(v: &Value) -> Option<Vec<i64>> {
    Some(match v {
        Value::IntVec(a) => a.iter().map(|&x| x as i64).collect(),
        Value::Int64Vec(a) => a.clone(),
        Value::UintVec(a) => a.iter().map(|&x| x as i64).collect(),
        _ => return None,
    })
}

fn kind(v: &Value) -> String {
    let s = format!("{v:?}");
    s.split(['(', ' ', '{']).next().unwrap_or("?").to_string()
}

// ---- transforms ----

/// The prim's local transform and whether it resets the parent's (`!resetXformStack!`).
fn local_transform(path: &Path, prim: &Prim) -> Result<(DMat4, bool)> {
    let Some(order) = value(path, prim, "xformOpOrder")? else {
        return Ok((DMat4::IDENTITY, false));
    };
    let ops: Vec<String> = match order {
        Value::TokenVec(t) => t.iter().map(|t| t.as_str().to_string()).collect(),
        other => {
            return Err(prim_err(
                path,
                prim.path(),
                format!("xformOpOrder is {}, expected token[]", kind(&other)),
            ))
        }
    };
    let mut m = DMat4::IDENTITY;
    let mut reset = false;
    for op in &ops {
        if op == "!resetXformStack!" {
            m = DMat4::IDENTITY;
            reset = true;
            continue;
        }
        let (name, invert) = match op.strip_prefix("!invert!") {
            Some(n) => (n, true),
            None => (op.as_str(), false),
        };
        let op_m = xform_op(path, prim, name)?;
        m *= if invert { op_m.inverse() } else { op_m };
    }
    Ok((m, reset))
}

/// One `xformOp:<type>[:suffix]` as a column-vector matrix.
fn xform_op(path: &Path, prim: &Prim, name: &str) -> Result<DMat4> {
    let at = property_path(path, prim.path(), name)?;
    let bad = |what: String| prim_err(path, &at, what);
    let ty = name
        .strip_prefix("xformOp:")
        .map(|r| r.split(':').next().unwrap_or(""))
        .ok_or_else(|| bad("is listed in xformOpOrder but is not an xformOp (re-export)".into()))?;
    let v = attr_value(path, prim.stage(), &at)?
        .ok_or_else(|| bad("is listed in xformOpOrder but has no value (re-export)".into()))?;
    let want3 = || vec3(&v).ok_or_else(|| bad(format!("is {}, expected a 3-vector", kind(&v))));
    let want1 = || scalar(&v).ok_or_else(|| bad(format!("is {}, expected a number", kind(&v))));
    let axis_rot = |axis: char, deg: f64| match axis {
        'X' => DMat4::from_rotation_x(deg.to_radians()),
        'Y' => DMat4::from_rotation_y(deg.to_radians()),
        _ => DMat4::from_rotation_z(deg.to_radians()),
    };
    Ok(match ty {
        "translate" => DMat4::from_translation(want3()?),
        "scale" => match scalar(&v) {
            Some(s) => DMat4::from_scale(DVec3::splat(s)),
            None => DMat4::from_scale(want3()?),
        },
        "rotateX" | "rotateY" | "rotateZ" => axis_rot(ty.chars().last().unwrap_or('X'), want1()?),
        "orient" => {
            let q = match &v {
                Value::Quatf(q) => DQuat::from_xyzw(q.x as f64, q.y as f64, q.z as f64, q.w as f64),
                Value::Quatd(q) => DQuat::from_xyzw(q.x, q.y, q.z, q.w),
                Value::Quath(q) => {
                    DQuat::from_xyzw(q.x.to_f64(), q.y.to_f64(), q.z.to_f64(), q.w.to_f64())
                }
                _ => return Err(bad(format!("is {}, expected a quaternion", kind(&v)))),
            };
            DMat4::from_quat(q.normalize())
        }
        "transform" => match &v {
            // USD matrices are row-major with row vectors: its rows are glam's columns.
            Value::Matrix4d(m) => DMat4::from_cols_array(&m.0),
            _ => return Err(bad(format!("is {}, expected matrix4d", kind(&v)))),
        },
        t if t.len() == 9 && t.starts_with("rotate") => {
            // rotateABC: about A first, then B, then C; the value is always (x, y, z) degrees.
            let angles = want3()?;
            let deg = |c: char| match c {
                'X' => angles.x,
                'Y' => angles.y,
                _ => angles.z,
            };
            let mut r = DMat4::IDENTITY;
            for c in t[6..].chars() {
                if !matches!(c, 'X' | 'Y' | 'Z') {
                    return Err(bad(format!("unknown rotation order '{t}'")));
                }
                r = axis_rot(c, deg(c)) * r;
            }
            r
        }
        other => {
            return Err(bad(format!(
                "unknown xformOp type '{other}' (re-export with translate/rotate/scale ops)"
            )))
        }
    })
}

// ---- meshes ----

struct Loader<'a> {
    path: &'a Path,
    opts: &'a MeshOptions,
    stage: &'a Stage,
    mesh: BaseMesh,
    any_uv_missing: bool,
    /// The material prim of each of `mesh.materials` (a material bound to several meshes is
    /// read once).
    material_paths: Vec<sdf::Path>,
    /// Names (path, prim name), world transform, projection and film aspect of each camera,
    /// in the stage's order.
    cameras: Vec<(Vec<String>, DMat4, Projection, Option<f32>)>,
    /// The UsdLux lights the beauty does not render ("/Key (RectLight)"), for one warning.
    unread_lights: Vec<String>,
}

/// A primvar expanded to one value per face corner.
enum Interp {
    Constant,
    Uniform,
    Vertex,
    FaceVarying,
}

impl Loader<'_> {
    /// `prim` at level `depth` (1: a child of the root) and everything under it.
    fn visit(&mut self, prim: &Prim, parent: DMat4, depth: usize) -> Result<()> {
        check_depth(self.path, prim, depth)?;
        if !is_renderable(self.path, prim)? {
            return Ok(());
        }
        let (local, reset) = local_transform(self.path, prim)?;
        let world = if reset { local } else { parent * local };
        match type_name(prim).as_str() {
            "Mesh" => self.mesh_prim(prim, world)?,
            "Camera" => self.camera_prim(prim, world)?,
            t @ ("DomeLight" | "DomeLight_1") => self.dome_prim(prim, world, t == "DomeLight_1")?,
            "DistantLight" => self.sun_prim(prim, world)?,
            "SphereLight" => self.sphere_prim(prim, world)?,
            t @ ("RectLight" | "DiskLight") => self.area_prim(prim, world, t == "DiskLight")?,
            t @ ("CylinderLight" | "GeometryLight" | "PortalLight" | "PluginLight") => {
                self.unread_lights.push(format!("{} ({t})", prim.path()))
            }
            _ => {}
        }
        for child in children(self.path, prim)? {
            self.visit(&child, world, depth + 1)?;
        }
        Ok(())
    }

    /// A `Camera` prim (UsdGeomCamera): looking down its local −Z with +Y up, as glTF's; the
    /// vertical field of view from `verticalAperture` and `focalLength` (both in the same
    /// tenths of a scene unit, so their ratio is the field of view; USD's defaults 15.2908 and
    /// 50 where not authored); an orthographic camera's view is `verticalAperture` tenths of
    /// a scene unit tall. `horizontalAperture` (20.955) over `verticalAperture` is the film
    /// aspect, which widens the view of an image narrower than the film back (USD's
    /// `expandAperture`). A camera of another projection is left out with a warning, and so
    /// is one whose values are not numbers; a view that cannot be rendered through is left
    /// out by `attach_camera`.
    fn camera_prim(&mut self, prim: &Prim, world: DMat4) -> Result<()> {
        let projection = value(self.path, prim, "projection")?;
        let projection = projection.as_ref().and_then(|v| v.as_str());
        let orthographic = projection == Some("orthographic");
        if projection.is_some_and(|p| p != "perspective") && !orthographic {
            warn(
                self.path,
                &format!(
                    "camera {} is {}: only perspective and orthographic cameras are read; left out",
                    prim.path(),
                    projection.unwrap_or_default()
                ),
            );
            return Ok(());
        }
        let read = |name: &str, default: f64| -> Result<Option<f64>> {
            Ok(match value(self.path, prim, name)? {
                None => Some(default),
                Some(v) => scalar(&v),
            })
        };
        let (Some(focal), Some(aperture), Some(width)) = (
            read("focalLength", 50.0)?,
            read("verticalAperture", 15.2908)?,
            read("horizontalAperture", 20.955)?,
        ) else {
            warn(
                self.path,
                &format!(
                    "camera {}: focalLength, verticalAperture or horizontalAperture is not a \
                     number; left out (re-export)",
                    prim.path()
                ),
            );
            return Ok(());
        };
        // A film back of no width, or a width that is not a finite positive number, does not
        // widen the view (the vertical aperture alone, as before).
        let film_aspect = Some((width / aperture) as f32).filter(|a| a.is_finite() && *a > 0.0);
        let projection = match orthographic {
            true => Projection::Orthographic {
                height: (aperture / 10.0) as f32,
            },
            false => Projection::Perspective {
                yfov_deg: (2.0 * (aperture / (2.0 * focal)).atan()).to_degrees() as f32,
            },
        };
        let path = prim.path().to_string();
        let name = path.rsplit('/').next().unwrap_or_default().to_string();
        self.cameras
            .push((vec![path, name], world, projection, film_aspect));
        Ok(())
    }

    /// A `DomeLight` (or `DomeLight_1`): its texture, tint and turn about the stage's up axis
    /// (`SceneDome`); the first one lights the beauty, a later one is left out with a warning.
    /// The dome's default orientation is OpenEXR's latitude-longitude map with its pole on +Y
    /// (`DomeLight_1`: on the stage's up axis, its `poleAxis` fallback `scene`); a transform
    /// that tilts the pole off the stage's up axis keeps only its turn about it, with a
    /// warning, and a texture in another parameterisation leaves the dome out.
    fn dome_prim(&mut self, prim: &Prim, world: DMat4, v1: bool) -> Result<()> {
        let (path, at) = (self.path, prim.path().clone());
        if let Some(first) = &self.mesh.dome {
            warn(
                path,
                &format!(
                    "{at}: a second dome light; the first, {}, lights the beauty",
                    first.name
                ),
            );
            return Ok(());
        }
        let (intensity, color) = self.light_power(&at, 1.0)?;
        let format = token_input(path, self.stage, &at, "texture:format")?;
        if let Some(f) = format
            .as_deref()
            .filter(|f| !matches!(*f, "automatic" | "latlong"))
        {
            warn(
                path,
                &format!(
                    "{at}: the dome's texture is {f}; only latitude-longitude maps are read, so \
                     the dome is left out (convert it to latlong, or give --env)"
                ),
            );
            return Ok(());
        }
        let texture = match input_value(path, self.stage, &at, "texture:file")? {
            Some(Value::AssetPath(a)) if !a.asset_path().is_empty() => Some(resolve_asset(
                path,
                self.stage,
                &at,
                "inputs:texture:file",
                &a,
            )),
            _ => None,
        };
        // The dome's own frame in the stage's Y-up terms (a Z-up stage's (x, z, −y)): its
        // pole and the direction its map's centre faces.
        let pole_axis = match v1 {
            true => value(path, prim, "poleAxis")?.and_then(|v| v.as_str().map(str::to_string)),
            false => None,
        };
        let lift = match (v1, pole_axis.as_deref().unwrap_or("scene")) {
            (true, "Z") => true,
            (true, "scene") => self.z_up(),
            _ => false,
        };
        let m = match lift {
            true => world * DMat4::from_rotation_x(90f64.to_radians()),
            false => world,
        };
        let pole = self
            .to_frame(m.transform_vector3(DVec3::Y))
            .normalize_or_zero();
        let centre = self.to_frame(m.transform_vector3(DVec3::Z));
        let tilt = pole.dot(DVec3::Y).clamp(-1.0, 1.0).acos().to_degrees();
        if tilt > 1.0 {
            warn(
                path,
                &format!(
                    "{at}: the dome's pole is tilted {tilt:.0}° from the stage's up axis; only its \
                     turn about the up axis is used (align it, e.g. DomeLight_1 with poleAxis \
                     \"scene\")"
                ),
            );
        }
        let turn_deg = centre.x.atan2(centre.z).to_degrees() as f32;
        let tint = (color * intensity).as_vec3().to_array();
        if !tint.iter().all(|c| c.is_finite() && *c >= 0.0) {
            warn(
                path,
                &format!(
                    "{at}: its colour × intensity × 2^exposure is ({}, {}, {}), not a radiance \
                     (finite, not negative); the dome is left out (fix the light)",
                    tint[0], tint[1], tint[2]
                ),
            );
            return Ok(());
        }
        self.mesh.dome = Some(SceneDome {
            name: at.to_string(),
            texture,
            tint,
            turn_deg: if turn_deg.is_finite() { turn_deg } else { 0.0 },
        });
        Ok(())
    }

    /// A `DistantLight`: the first is the key light (`SceneSun`), pointing where the prim's
    /// transform turns its −Z; a later one lights beside it (`BaseMesh::lights`). UsdLux's
    /// `intensity` (fallback 50 000 for this light) is the disc's luminance: its irradiance is
    /// that times the disc's solid angle, `2π(1 − cos(angle/2))` (3.4 for the fallbacks, a
    /// sun's), unless `inputs:normalize` makes the intensity the irradiance itself, as a light
    /// of no angle has it too.
    fn sun_prim(&mut self, prim: &Prim, world: DMat4) -> Result<()> {
        let (path, at) = (self.path, prim.path().clone());
        let (intensity, rgb) = self.light_power(&at, 50_000.0)?;
        let (luminance, color) = crate::mesh::split_color(rgb.as_vec3())
            .map_or((f64::NAN, [1.0; 3]), |(l, c)| (l as f64, c));
        let angle = self.light_number(
            &at,
            "angle",
            0.53,
            |x| x.is_finite() && x >= 0.0,
            "expected degrees >= 0",
        )?;
        let normalize = self.light_flag(&at, "normalize")?;
        let solid_angle = std::f64::consts::TAU * (1.0 - (0.5 * angle).to_radians().cos());
        let irradiance = match normalize || angle == 0.0 {
            true => intensity,
            false => intensity * solid_angle,
        };
        let toward = self
            .to_frame(world.transform_vector3(DVec3::Z))
            .normalize_or_zero();
        if toward == DVec3::ZERO {
            warn(
                path,
                &format!("{at}: its transform collapses its direction; left out"),
            );
            return Ok(());
        }
        let irradiance = (irradiance * luminance) as f32;
        if !(irradiance.is_finite() && irradiance >= 0.0) {
            warn(
                path,
                &format!(
                    "{at}: its irradiance comes to {irradiance}, not a finite, non-negative \
                     number; left out (fix its intensity, exposure or colour ({}, {}, {}))",
                    rgb.x, rgb.y, rgb.z
                ),
            );
            return Ok(());
        }
        let max = crate::render::lookdev::MAX_KEY_ANGLE_DEG as f64;
        if self.mesh.sun.is_some() {
            // A later one lights beside the key, in the mesh's own frame.
            let dir = world.transform_vector3(DVec3::Z).normalize().as_vec3();
            self.mesh.lights.push(crate::mesh::SceneLight {
                name: at.to_string(),
                light: Light {
                    shape: LightShape::Distant {
                        dir,
                        cos_radius: (0.5 * angle.min(max)).to_radians().cos() as f32,
                    },
                    power: irradiance,
                    color: Vec3::from_array(color),
                },
            });
            return Ok(());
        }
        let elevation = toward.y.clamp(-1.0, 1.0).asin().to_degrees();
        let azimuth = toward.x.atan2(toward.z).to_degrees();
        self.mesh.sun = Some(SceneSun {
            name: at.to_string(),
            key: [azimuth as f32, elevation as f32, irradiance],
            color,
            angle_deg: angle.min(max) as f32,
        });
        Ok(())
    }

    /// A `SphereLight`: a sphere of radius `inputs:radius` (0.5, scaled with the prim) at its
    /// prim's origin, or a point where `treatAsPoint` says so, of intensity (W/sr, the
    /// luminance of `inputs:color` times) UsdLux's radiance `inputs:intensity ×
    /// 2^inputs:exposure` times the sphere's disc, πr², or, `inputs:normalize`d, over its whole
    /// area, intensity / 4: Blender's exporter writes a lamp of P watts as intensity P / π,
    /// normalized, a 4π-th of P a steradian. With `ShapingAPI`'s `shaping:cone:angle` below
    /// 90°, a spot down its −Z whose edge fades as a Cycles spot of blend
    /// `shaping:cone:softness` (Blender's importer's mapping; `Spot::blended`). A light of no radius that is not
    /// normalized casts nothing, and one whose numbers are not usable is left out, with a
    /// warning.
    fn sphere_prim(&mut self, prim: &Prim, world: DMat4) -> Result<()> {
        let (path, at) = (self.path, prim.path().clone());
        let (intensity, rgb) = self.light_power(&at, 1.0)?;
        let number = |name: &str, default: f64, ok: fn(f64) -> bool| {
            self.light_number(&at, name, default, ok, "out of range")
        };
        let radius = number("radius", 0.5, |r| r.is_finite() && r >= 0.0)?;
        let cone = number("shaping:cone:angle", 90.0, |a| a.is_finite() && a > 0.0)?;
        let softness = number("shaping:cone:softness", 0.0, |s| (0.0..=1.0).contains(&s))?;
        let normalize = self.light_flag(&at, "normalize")?;
        let as_point = matches!(value(path, prim, "treatAsPoint")?, Some(Value::Bool(true)));
        let scale = world.transform_vector3(DVec3::X).length();
        let r = radius * scale;
        let (luminance, color) = crate::mesh::split_color(rgb.as_vec3())
            .map_or((f64::NAN, [1.0; 3]), |(l, c)| (l as f64, c));
        let power = match normalize {
            true => intensity / 4.0,
            false => intensity * std::f64::consts::PI * r * r,
        } * luminance;
        let pos = world.transform_point3(DVec3::ZERO).as_vec3();
        let axis = world
            .transform_vector3(DVec3::NEG_Z)
            .normalize_or_zero()
            .as_vec3();
        let power = power as f32;
        let unusable = !(power.is_finite() && power >= 0.0 && pos.is_finite() && r.is_finite());
        if unusable || (!normalize && r == 0.0) || (cone < 90.0 && axis == Vec3::ZERO) {
            let why = match unusable {
                true => format!(
                    "its intensity comes to {power} (intensity, exposure, colour ({}, {}, {}), \
                     radius {r}), not a finite, non-negative number",
                    rgb.x, rgb.y, rgb.z
                ),
                false if !normalize && r == 0.0 => {
                    "it has no radius and is not normalized: it casts nothing (give it a \
                     radius, or inputs:normalize)"
                        .to_string()
                }
                false => "its transform collapses its cone's axis".to_string(),
            };
            warn(path, &format!("{at}: {why}; left out"));
            return Ok(());
        }
        let spot =
            (cone < 90.0).then(|| Spot::blended(axis, cone.to_radians() as f32, softness as f32));
        self.mesh.lights.push(crate::mesh::SceneLight {
            name: at.to_string(),
            light: Light {
                shape: LightShape::Local {
                    pos,
                    radius: if as_point { 0.0 } else { r as f32 },
                    spot,
                },
                power,
                color: Vec3::from_array(color),
            },
        });
        Ok(())
    }

    /// A `RectLight` (`inputs:width` × `inputs:height`, 1 × 1) or `DiskLight` (`inputs:radius`,
    /// 0.5) centred on its prim's origin in its XY plane, scaled with the prim, shining along
    /// its −Z: of radiance UsdLux's `inputs:intensity × 2^inputs:exposure` (1 where not
    /// authored; the luminance of `inputs:color` times), over its area where
    /// `inputs:normalize`d (Blender writes an area lamp of P watts as intensity P / π,
    /// normalized: Cycles' radiance P / (π × area)). A rect light's texture is not read (a
    /// warning); one whose numbers are not usable is left out, with a warning.
    fn area_prim(&mut self, prim: &Prim, world: DMat4, disk: bool) -> Result<()> {
        let (path, at) = (self.path, prim.path().clone());
        let (intensity, rgb) = self.light_power(&at, 1.0)?;
        let number = |name: &str, default: f64| {
            let ok = |x: f64| x.is_finite() && x >= 0.0;
            self.light_number(&at, name, default, ok, "expected a size >= 0")
        };
        let (half_w, half_h) = match disk {
            true => {
                let r = number("radius", 0.5)?;
                (r, r)
            }
            false => (0.5 * number("width", 1.0)?, 0.5 * number("height", 1.0)?),
        };
        if !disk && input_value(path, self.stage, &at, "texture:file")?.is_some() {
            warn(
                path,
                &format!("{at}: its texture is not read; it shines its colour evenly"),
            );
        }
        let normalize = self.light_flag(&at, "normalize")?;
        let u = (world.transform_vector3(DVec3::X) * half_w).as_vec3();
        let v = (world.transform_vector3(DVec3::Y) * half_h).as_vec3();
        let (area, _) = crate::render::lights::area_and_normal(u, v, disk);
        let (luminance, color) = crate::mesh::split_color(rgb.as_vec3())
            .map_or((f64::NAN, [1.0; 3]), |(l, c)| (l as f64, c));
        let radiance = match normalize {
            true => intensity / area as f64,
            false => intensity,
        } * luminance;
        let radiance = radiance as f32;
        let pos = world.transform_point3(DVec3::ZERO).as_vec3();
        if !(radiance.is_finite() && radiance >= 0.0 && area > 0.0 && pos.is_finite()) {
            warn(
                path,
                &format!(
                    "{at}: its radiance comes to {radiance} over an area of {area} (intensity, \
                     exposure, colour ({}, {}, {}), size), not usable; left out",
                    rgb.x, rgb.y, rgb.z
                ),
            );
            return Ok(());
        }
        self.mesh.lights.push(crate::mesh::SceneLight {
            name: at.to_string(),
            light: Light {
                shape: LightShape::Area { pos, u, v, disk },
                power: radiance,
                color: Vec3::from_array(color),
            },
        });
        Ok(())
    }

    /// A light's `inputs:intensity × 2^inputs:exposure` and `inputs:color` (UsdLux's
    /// fallbacks `intensity`, 0 and white), the colour times a black body's at
    /// `inputs:colorTemperature` (6 500 K) where `inputs:enableColorTemperature` is set
    /// (`lights::blackbody`); a value that is not a number is an error naming it.
    fn light_power(&self, at: &sdf::Path, intensity: f64) -> Result<(f64, DVec3)> {
        let path = self.path;
        let number = |name: &str, default: f64| {
            self.light_number(at, name, default, f64::is_finite, "expected a number")
        };
        let intensity = number("intensity", intensity)? * number("exposure", 0.0)?.exp2();
        let color = match input_value(path, self.stage, at, "color")? {
            None => DVec3::ONE,
            Some(v) => vec3(&v).filter(|c| c.is_finite()).ok_or_else(|| {
                let what = format!("inputs:color is {}, expected color3f (re-export)", kind(&v));
                prim_err(path, at, what)
            })?,
        };
        let color = match self.light_flag(at, "enableColorTemperature")? {
            true => {
                let kelvin = number("colorTemperature", 6500.0)?;
                color * crate::render::lights::blackbody(kelvin as f32).as_dvec3()
            }
            false => color,
        };
        Ok((intensity, color))
    }

    /// A light's number input `inputs:NAME` (following connections), `default` where not
    /// authored; one that is not a number, or that `ok` refuses, is an error naming it and
    /// saying what was `expected`.
    fn light_number(
        &self,
        at: &sdf::Path,
        name: &str,
        default: f64,
        ok: fn(f64) -> bool,
        expected: &str,
    ) -> Result<f64> {
        match input_value(self.path, self.stage, at, name)? {
            None => Ok(default),
            Some(v) => scalar(&v).filter(|x| ok(*x)).ok_or_else(|| {
                let what = format!("inputs:{name} is {}, {expected} (re-export)", kind(&v));
                prim_err(self.path, at, what)
            }),
        }
    }

    /// Whether a light's bool input `inputs:NAME` is authored true.
    fn light_flag(&self, at: &sdf::Path, name: &str) -> Result<bool> {
        Ok(matches!(
            input_value(self.path, self.stage, at, name)?,
            Some(Value::Bool(true))
        ))
    }

    fn z_up(&self) -> bool {
        self.mesh.up_axis == Some(UpAxis::Z)
    }

    /// A world direction in the stage's Y-up terms (a Z-up stage's (x, z, −y)): the frame the
    /// environment and `--key-light`'s angles are in.
    fn to_frame(&self, d: DVec3) -> DVec3 {
        match self.z_up() {
            true => DVec3::new(d.x, d.z, -d.y),
            false => d,
        }
    }

    fn array<T>(
        &self,
        prim: &Prim,
        name: &str,
        conv: fn(&Value) -> Option<Vec<T>>,
        want: &str,
    ) -> Result<Option<Vec<T>>> {
        match value(self.path, prim, name)? {
            None => Ok(None),
            Some(v) => conv(&v).map(Some).ok_or_else(|| {
                prim_err(
                    self.path,
                    prim.path(),
                    format!("{name} is {}, expected {want} (re-export)", kind(&v)),
                )
            }),
        }
    }

    fn mesh_prim(&mut self, prim: &Prim, world: DMat4) -> Result<()> {
        let (path, at) = (self.path, prim.path().clone());
        let points = self
            .array(prim, "points", vec3_array, "point3f[]")?
            .unwrap_or_default();
        let counts = self
            .array(prim, "faceVertexCounts", int_array, "int[]")?
            .unwrap_or_default();
        let indices = self
            .array(prim, "faceVertexIndices", int_array, "int[]")?
            .unwrap_or_default();
        if points.is_empty() || counts.is_empty() {
            warn(path, &format!("{at}: mesh has no points or faces; skipped"));
            return Ok(());
        }
        let world32 = world.as_mat4();
        let linear = Mat3::from_mat4(world32);
        let det = linear.determinant();
        if det == 0.0 || !det.is_finite() {
            warn(path, &format!("{at}: singular transform; skipped"));
            return Ok(());
        }
        let n_points = points.len();
        // Faces: (first corner, corner count), checked against the index and point arrays.
        let mut faces = Vec::with_capacity(counts.len());
        let mut corner = 0usize;
        let mut skipped = 0usize;
        for (f, &c) in counts.iter().enumerate() {
            if c < 0 {
                return Err(prim_err(
                    path,
                    &at,
                    format!("faceVertexCounts[{f}] is {c}, negative (re-export)"),
                ));
            }
            let c = c as usize;
            if corner + c > indices.len() {
                return Err(prim_err(
                    path,
                    &at,
                    format!(
                        "faceVertexCounts need more than the {} faceVertexIndices (face {f}; the mesh is truncated, re-export)",
                        indices.len()
                    ),
                ));
            }
            if c < 3 {
                skipped += 1;
            }
            faces.push((corner, c));
            corner += c;
        }
        let n_corners = corner;
        if let Some((k, &i)) = indices[..n_corners]
            .iter()
            .enumerate()
            .find(|(_, &i)| i < 0 || i as usize >= n_points)
        {
            return Err(prim_err(
                path,
                &at,
                format!(
                    "faceVertexIndices[{k}] is {i} but the mesh has {n_points} points (re-export)"
                ),
            ));
        }
        if skipped > 0 {
            warn(
                path,
                &format!("{at}: {skipped} faces with fewer than 3 corners skipped"),
            );
        }
        let point_of = |k: usize| indices[k] as usize;

        let flip = (det < 0.0)
            != (value(path, prim, "orientation")?
                .as_ref()
                .and_then(|v| v.as_str())
                == Some("leftHanded"));
        let mut tris: Vec<[usize; 3]> = Vec::new(); // corner indices
        let mut tri_face: Vec<usize> = Vec::new();
        for (f, &(first, c)) in faces.iter().enumerate() {
            for i in 1..c.saturating_sub(1) {
                let t = [first, first + i, first + i + 1];
                tris.push(if flip { [t[0], t[2], t[1]] } else { t });
                tri_face.push(f);
            }
        }

        let positions: Vec<Vec3> = points
            .iter()
            .map(|&p| world32.transform_point3(p))
            .collect();
        let point_tris: Vec<[u32; 3]> =
            tris.iter().map(|t| t.map(|k| point_of(k) as u32)).collect();
        let derived = BaseMesh::angle_weighted_normals(&positions, &point_tris);
        let normal_name = if value(path, prim, "primvars:normals")?.is_some() {
            "primvars:normals"
        } else {
            "normals"
        };
        let to_world = linear.inverse().transpose();
        let file_normals = self.corner_values(
            prim,
            normal_name,
            vec3_array,
            "normal3f[]",
            &faces,
            &indices,
            n_points,
            "vertex",
        )?;
        let (uvs, uv_name) = match self.corner_uvs(prim, &faces, &indices, n_points)? {
            Some((uvs, name)) => (Some(uvs), Some(name)),
            None => (None, None),
        };
        let material = self.material_index(prim, uv_name.as_deref())?;
        // Per face, its group among the mesh's own (0) and its material subsets'.
        let (subsets, face_slot) = self.material_subsets(prim, faces.len(), uv_name.as_deref())?;

        // One vertex per distinct (point, normal, UV) corner.
        let mut key_to_vertex: HashMap<(usize, [u32; 3], [u32; 2]), u32> = HashMap::new();
        let mut corner_vertex = vec![0u32; n_corners];
        let base = self.mesh.positions.len() as u32;
        let mut new_pos = Vec::new();
        let mut new_nrm = Vec::new();
        let mut new_uv = Vec::new();
        for &(first, c) in &faces {
            for k in first..first + c {
                let p = point_of(k);
                let n = match &file_normals {
                    Some(fv) => (to_world * fv[k]).try_normalize().unwrap_or(derived[p]),
                    None => derived[p],
                };
                let uv = uvs.as_ref().map_or(Vec2::ZERO, |u| u[k]);
                let key = (
                    p,
                    n.to_array().map(f32::to_bits),
                    uv.to_array().map(f32::to_bits),
                );
                corner_vertex[k] = *key_to_vertex.entry(key).or_insert_with(|| {
                    new_pos.push(positions[p]);
                    new_nrm.push(n);
                    new_uv.push(uv);
                    base + new_pos.len() as u32 - 1
                });
            }
        }
        let g = self.mesh.groups.len() as u32;
        self.mesh.groups.push(at.to_string());
        self.mesh.group_material.push(material);
        for (name, m) in subsets {
            self.mesh.groups.push(name);
            self.mesh.group_material.push(m);
        }
        self.mesh.positions.extend(new_pos);
        self.mesh.normals.extend(new_nrm);
        self.mesh.uvs.extend(new_uv);
        for (t, &f) in tris.iter().zip(&tri_face) {
            self.mesh.triangles.push(t.map(|k| corner_vertex[k]));
            self.mesh.face_group.push(g + face_slot[f]);
        }
        Ok(())
    }

    /// The mesh's `GeomSubset` children of family `materialBind` (Blender writes one per
    /// material slot of a mesh with several): each subset's (path, material) and, per face,
    /// its subset's number from 1 (0: none, the mesh's own material). A subset of another
    /// element type, or an index past the faces, is a warning: materials are read for the
    /// beauty alone.
    fn material_subsets(
        &mut self,
        prim: &Prim,
        n_faces: usize,
        uv_name: Option<&str>,
    ) -> Result<SubsetBinding> {
        let path = self.path;
        let mut subsets = vec![];
        let mut face_slot = vec![0u32; n_faces];
        for child in children(path, prim)? {
            if type_name(&child) != "GeomSubset" {
                continue;
            }
            let token = |name: &str| -> Result<Option<String>> {
                Ok(value(path, &child, name)?.and_then(|v| v.as_str().map(str::to_string)))
            };
            if token("familyName")?.as_deref() != Some("materialBind") {
                continue;
            }
            let at = child.path().to_string();
            if let Some(other) = token("elementType")?.filter(|t| t != "face") {
                warn(
                    path,
                    &format!("{at}: a material subset of {other}s, not faces: not read"),
                );
                continue;
            }
            let indices = self
                .array(&child, "indices", int_array, "int[]")?
                .unwrap_or_default();
            let material = self.material_index(&child, uv_name)?;
            subsets.push((at.clone(), material));
            let slot = subsets.len() as u32;
            let mut outside = 0;
            for i in indices {
                match usize::try_from(i).ok().filter(|&f| f < n_faces) {
                    Some(f) => face_slot[f] = slot,
                    None => outside += 1,
                }
            }
            if outside > 0 {
                warn(
                    path,
                    &format!(
                        "{at}: {outside} indices are not faces of the mesh's {n_faces}: ignored \
                         (re-export)"
                    ),
                );
            }
        }
        Ok((subsets, face_slot))
    }

    /// The UV primvar: `uv_set` 0 is the one the displacement texture reads (else `st`, else
    /// the first texCoord2 primvar by name), N > 0 the N-th of the others by name.
    fn corner_uvs(
        &mut self,
        prim: &Prim,
        faces: &[(usize, usize)],
        indices: &[i64],
        n_points: usize,
    ) -> Result<Option<(Vec<Vec2>, String)>> {
        let path = self.path;
        let mut names: Vec<String> = Vec::new();
        // By name, not `Prim::attributes`: that makes a path of every property name the file
        // lists, and a fuzzed binary layer's name with path syntax in it sent openusd's
        // ancestor walk (`Path::parent`) into an endless loop. Only `primvars:` names become
        // paths here, through `property_path`'s identifier check.
        for name in prim
            .property_names()
            .map_err(|e| usd_err(path, prim.path(), e))?
        {
            let Some(short) = name.as_str().strip_prefix("primvars:") else {
                continue;
            };
            if short.contains(':') {
                continue;
            }
            let attr = self
                .stage
                .attribute(property_path(path, prim.path(), name.as_str())?);
            let ty = attr
                .type_name()
                .ok()
                .flatten()
                .map(|t| t.as_str().to_string())
                .unwrap_or_default();
            if ty.starts_with("texCoord2")
                || (ty.starts_with("float2[") && matches!(short, "st" | "uv" | "UVMap"))
            {
                names.push(short.to_string());
            }
        }
        names.sort();
        let preferred = mesh_displacement(path, self.stage, prim)
            .ok()
            .flatten()
            .and_then(|d| d.uv_primvar)
            .unwrap_or_else(|| "st".to_string());
        if let Some(i) = names.iter().position(|n| *n == preferred) {
            let p = names.remove(i);
            names.insert(0, p);
        }
        if names.is_empty() {
            self.any_uv_missing = true;
            return Ok(None);
        }
        let set = self.opts.uv_set as usize;
        let Some(name) = names.get(set) else {
            return Err(prim_err(
                path,
                prim.path(),
                format!(
                    "has no UV set {set}; its UV primvars are {} (choose one with --uv-set 0..{})",
                    names.join(", "),
                    names.len() - 1
                ),
            ));
        };
        let full = format!("primvars:{name}");
        Ok(self
            .corner_values(
                prim,
                &full,
                vec2_array,
                "texCoord2f[]",
                faces,
                indices,
                n_points,
                "constant",
            )?
            .map(|uvs| (uvs, name.clone())))
    }

    /// The index into `mesh.materials` of the material bound to `prim` (read at its first
    /// mesh), or `u32::MAX` for none (`BaseMesh::face_material` takes it as none). `uv_name`:
    /// the UV primvar the mesh was loaded with.
    fn material_index(&mut self, prim: &Prim, uv_name: Option<&str>) -> Result<u32> {
        // Only the beauty reads materials: one it cannot read is a warning, not a failed load.
        let found = mesh_material(self.path, self.stage, prim, uv_name).unwrap_or_else(|e| {
            warn(
                self.path,
                &format!("{}: its material is not read: {e}", prim.path()),
            );
            None
        });
        let Some((at, mut material)) = found else {
            return Ok(u32::MAX);
        };
        material.set_tex_coord(self.opts.uv_set);
        if let Some(i) = self.material_paths.iter().position(|p| *p == at) {
            return Ok(i as u32);
        }
        if self.mesh.materials.len() >= MAX_MATERIALS {
            return Err(prim_err(
                self.path,
                &at,
                format!("is past the {MAX_MATERIALS} materials supported (merge materials)"),
            ));
        }
        self.material_paths.push(at);
        self.mesh.materials.push(material);
        Ok(self.mesh.materials.len() as u32 - 1)
    }

    /// An attribute or primvar expanded to one value per face corner (`None` when absent).
    #[allow(clippy::too_many_arguments)]
    fn corner_values<T: Copy>(
        &self,
        prim: &Prim,
        name: &str,
        conv: fn(&Value) -> Option<Vec<T>>,
        want: &str,
        faces: &[(usize, usize)],
        indices: &[i64],
        n_points: usize,
        default_interp: &str,
    ) -> Result<Option<Vec<T>>> {
        let path = self.path;
        let Some(mut vals) = self.array(prim, name, conv, want)? else {
            return Ok(None);
        };
        let at = property_path(path, prim.path(), name)?;
        let interp_tok = metadata_token(self.stage, &at, "interpolation")
            .unwrap_or_else(|| default_interp.to_string());
        let interp = match interp_tok.as_str() {
            "constant" => Interp::Constant,
            "uniform" => Interp::Uniform,
            "vertex" | "varying" => Interp::Vertex,
            "faceVarying" => Interp::FaceVarying,
            other => {
                return Err(prim_err(
                    path,
                    &at,
                    format!("unknown interpolation '{other}' (re-export)"),
                ))
            }
        };
        if let Some(v) = self
            .stage
            .attribute(at.clone())
            .get_metadata::<Value>("elementSize")
            .ok()
            .flatten()
        {
            if scalar(&v).is_some_and(|s| s != 1.0) {
                return Err(prim_err(path, &at, "elementSize other than 1 is not supported (re-export with one value per element)"));
            }
        }
        if name.starts_with("primvars:") {
            if let Some(idx) = self.array(prim, &format!("{name}:indices"), int_array, "int[]")? {
                let n = vals.len();
                if let Some((k, &i)) = idx
                    .iter()
                    .enumerate()
                    .find(|(_, &i)| i < 0 || i as usize >= n)
                {
                    return Err(prim_err(
                        path,
                        &at,
                        format!("{name}:indices[{k}] is {i} but there are {n} values (re-export)"),
                    ));
                }
                vals = idx.iter().map(|&i| vals[i as usize]).collect();
            }
        }
        let n_corners: usize = faces.last().map_or(0, |&(f, c)| f + c);
        let (expected, what) = match interp {
            Interp::Constant => (1, "1 (constant)"),
            Interp::Uniform => (faces.len(), "one per face (uniform)"),
            Interp::Vertex => (n_points, "one per point (vertex)"),
            Interp::FaceVarying => (n_corners, "one per face corner (faceVarying)"),
        };
        if vals.len() < expected {
            return Err(prim_err(
                path,
                &at,
                format!(
                    "has {} values, expected {what}: {expected} (re-export)",
                    vals.len()
                ),
            ));
        }
        let mut out = Vec::with_capacity(n_corners);
        for (f, &(first, c)) in faces.iter().enumerate() {
            for k in first..first + c {
                out.push(match interp {
                    Interp::Constant => vals[0],
                    Interp::Uniform => vals[f],
                    Interp::Vertex => vals[indices[k] as usize],
                    Interp::FaceVarying => vals[k],
                });
            }
        }
        Ok(Some(out))
    }
}

// ---- materials ----

/// The material bound to the prim or its nearest ancestor (`material:binding`, then the
/// `full` and `preview` purposes).
fn bound_material(path: &Path, stage: &Stage, prim: &sdf::Path) -> Result<Option<sdf::Path>> {
    let mut p = Some(prim.clone());
    while let Some(cur) = p {
        if cur.is_abs_root() {
            break;
        }
        for rel in [
            "material:binding",
            "material:binding:full",
            "material:binding:preview",
        ] {
            let rp = property_path(path, &cur, rel)?;
            let targets = stage
                .relationship(rp.clone())
                .targets()
                .map_err(|e| usd_err(path, &rp, e))?;
            if let Some(t) = targets.into_iter().next() {
                return checked_target(path, &rp, t).map(Some);
            }
        }
        p = cur.parent();
    }
    Ok(None)
}

fn info_id(path: &Path, stage: &Stage, shader: &sdf::Path) -> Result<Option<String>> {
    let p = property_path(path, shader, "info:id")?;
    Ok(attr_value(path, stage, &p)?.and_then(|v| v.as_str().map(str::to_string)))
}

/// Follow connections from an input or output attribute through node graphs to the shader
/// output that feeds it: `(shader prim, output name)`; `None` if it ends in a plain value.
fn connected_output(
    path: &Path,
    stage: &Stage,
    attr: &sdf::Path,
) -> Result<Option<(sdf::Path, String)>> {
    let mut cur = attr.clone();
    for _ in 0..32 {
        let conns = stage
            .attribute(cur.clone())
            .connections()
            .map_err(|e| usd_err(path, &cur, e))?;
        let Some(target) = conns.into_iter().next() else {
            return Ok(None);
        };
        let target = checked_target(path, &cur, target)?;
        let Some((prim, prop)) = target.split_property() else {
            return Err(prim_err(
                path,
                &cur,
                format!("connects to {target}, which is not a property (re-export)"),
            ));
        };
        if let Some(out) = prop.strip_prefix("outputs:") {
            if info_id(path, stage, &prim)?.is_some() {
                return Ok(Some((prim, out.to_string())));
            }
        }
        cur = target.clone();
    }
    Err(prim_err(
        path,
        attr,
        "connection chain is longer than 32 links or cyclic (re-export)",
    ))
}

/// A shader input's value, following connections to node-graph interface inputs.
fn input_value(
    path: &Path,
    stage: &Stage,
    shader: &sdf::Path,
    name: &str,
) -> Result<Option<Value>> {
    let mut cur = property_path(path, shader, &format!("inputs:{name}"))?;
    for _ in 0..32 {
        let conns = stage
            .attribute(cur.clone())
            .connections()
            .map_err(|e| usd_err(path, &cur, e))?;
        match conns.into_iter().next() {
            Some(t) => cur = checked_target(path, &cur, t)?,
            None => return attr_value(path, stage, &cur),
        }
    }
    Err(prim_err(
        path,
        &cur,
        "connection chain is longer than 32 links or cyclic (re-export)",
    ))
}

fn token_input(
    path: &Path,
    stage: &Stage,
    shader: &sdf::Path,
    name: &str,
) -> Result<Option<String>> {
    Ok(input_value(path, stage, shader, name)?.and_then(|v| v.as_str().map(str::to_string)))
}

/// The texture-driven displacement of one mesh prim, if its material has one.
fn mesh_displacement(path: &Path, stage: &Stage, prim: &Prim) -> Result<Option<UsdDisplacement>> {
    let Some(material) = bound_material(path, stage, prim.path())? else {
        return Ok(None);
    };
    // The material's displacement output leads to the surface shader; a material that only
    // wires `outputs:surface` still gets its preview surface's displacement read.
    let mut surface = None;
    for out in ["outputs:displacement", "outputs:surface"] {
        let p = property_path(path, &material, out)?;
        if let Some((shader, _)) = connected_output(path, stage, &p)? {
            surface = Some(shader);
            break;
        }
    }
    let Some(surface) = surface else {
        return Ok(None);
    };
    if info_id(path, stage, &surface)?.as_deref() != Some("UsdPreviewSurface") {
        return Ok(None);
    }
    let disp_in = property_path(path, &surface, "inputs:displacement")?;
    let Some((tex, output)) = connected_output(path, stage, &disp_in)? else {
        return Ok(None);
    };
    let id = info_id(path, stage, &tex)?.unwrap_or_default();
    if id != "UsdUVTexture" {
        return Err(prim_err(
            path,
            &disp_in,
            format!("is driven by a {id} shader ({tex}); only a UsdUVTexture is supported (connect the height texture directly)"),
        ));
    }
    let channel = match output.as_str() {
        "r" | "rgb" | "rgba" => 0,
        "g" => 1,
        "b" => 2,
        "a" => 3,
        other => {
            return Err(prim_err(
                path,
                &disp_in,
                format!("reads output '{other}' of {tex}; expected r, g, b or a"),
            ))
        }
    };
    let Some(file) = texture_file(path, stage, &tex)? else {
        return Err(prim_err(
            path,
            &tex,
            "the displacement texture has no inputs:file (set the height map's path)",
        ));
    };
    let four = |name: &str, default: [f64; 4]| -> Result<[f64; 4]> {
        Ok(typed_input(path, stage, &tex, name, vec4, "float4")?.unwrap_or(default))
    };
    let scale = four("scale", [1.0; 4])?[channel];
    let bias = four("bias", [0.0; 4])?[channel];
    if scale == 0.0 || !scale.is_finite() || !bias.is_finite() {
        return Err(prim_err(
            path,
            &tex,
            format!("inputs:scale is {scale} for the displacement channel: D = scale·h + bias needs a finite, non-zero scale (fix the material, or pass --scale/--midlevel)"),
        ));
    }
    let wrap_s = token_input(path, stage, &tex, "wrapS")?;
    let wrap_t = token_input(path, stage, &tex, "wrapT")?;
    if wrap_s != wrap_t {
        warn(
            path,
            &format!("{tex}: wrapS {wrap_s:?} and wrapT {wrap_t:?} differ; wrapS is used for both"),
        );
    }
    let wrap = match wrap_s.as_deref() {
        None | Some("useMetadata") | Some("repeat") => Wrap::Repeat,
        Some("clamp") => Wrap::Clamp,
        Some(other) => {
            warn(
                path,
                &format!("{tex}: wrap mode '{other}' is not supported; repeat is used"),
            );
            Wrap::Repeat
        }
    };
    if token_input(path, stage, &tex, "sourceColorSpace")?.as_deref() == Some("sRGB") {
        warn(
            path,
            &format!("{tex}: sourceColorSpace is sRGB; height maps are read raw (set it to raw)"),
        );
    }
    let st_in = property_path(path, &tex, "inputs:st")?;
    let uv_primvar = match connected_output(path, stage, &st_in)? {
        None => None,
        Some((reader, _)) => {
            let id = info_id(path, stage, &reader)?.unwrap_or_default();
            if !id.starts_with("UsdPrimvarReader") {
                return Err(prim_err(
                    path,
                    &st_in,
                    format!("comes from a {id} shader ({reader}); only a UsdPrimvarReader_float2 is supported (bake UV transforms into the primvar)"),
                ));
            }
            token_input(path, stage, &reader, "varname")?
        }
    };
    Ok(Some(UsdDisplacement {
        file,
        scale: scale as f32,
        midlevel: (-bias / scale) as f32,
        wrap,
        channel: ["R", "G", "B", "A"][channel].to_string(),
        uv_primvar,
    }))
}

/// The material bound to a mesh prim as the beauty reads it, if it is a `UsdPreviewSurface`:
/// `diffuseColor` (a value, or a `UsdUVTexture`'s `rgb` read through the mesh's UV primvar
/// `uv_name`), `roughness` and `metallic` (values, UsdPreviewSurface's defaults where
/// unauthored, or one channel of a `UsdUVTexture`), `ior`, `clearcoat` and
/// `clearcoatRoughness` (values), and the emission. Returns the material prim too.
fn mesh_material(
    path: &Path,
    stage: &Stage,
    prim: &Prim,
    uv_name: Option<&str>,
) -> Result<Option<(sdf::Path, MeshMaterial)>> {
    let Some(material) = bound_material(path, stage, prim.path())? else {
        return Ok(None);
    };
    let out = property_path(path, &material, "outputs:surface")?;
    let Some((surface, _)) = connected_output(path, stage, &out)? else {
        return Ok(None);
    };
    if info_id(path, stage, &surface)?.as_deref() != Some("UsdPreviewSurface") {
        return Ok(None);
    }
    let float = |name: &str, default: f32| -> Result<f32> {
        Ok(match input_value(path, stage, &surface, name)? {
            Some(v) => scalar(&v).map_or(default, |x| (x as f32).clamp(0.0, 1.0)),
            None => default,
        })
    };
    // UsdPreviewSurface's default diffuseColor.
    let mut m = MeshMaterial::plain(
        material.to_string(),
        [0.18, 0.18, 0.18, 1.0],
        float("roughness", 0.5)?,
        float("metallic", 0.0)?,
    );
    let diffuse = property_path(path, &surface, "inputs:diffuseColor")?;
    match connected_output(path, stage, &diffuse)? {
        Some((tex, _)) if info_id(path, stage, &tex)?.as_deref() == Some("UsdUVTexture") => {
            m.base_color = [1.0; 4];
            m.base_color_texture = uv_texture(path, stage, &tex, uv_name, "diffuse")?;
        }
        Some((shader, _)) => warn(
            path,
            &format!(
                "{}: diffuseColor comes from {shader}, not a UsdUVTexture: not read",
                material
            ),
        ),
        None => {
            if let Some(c) = input_value(path, stage, &surface, "diffuseColor")?
                .as_ref()
                .and_then(vec3)
            {
                m.base_color = [c.x as f32, c.y as f32, c.z as f32, 1.0];
            }
        }
    }
    // ior (UsdPreviewSurface's default 1.5: F0 0.04) for the dielectric reflectance.
    if let Some(ior) = input_value(path, stage, &surface, "ior")?
        .as_ref()
        .and_then(scalar)
    {
        m.specular = crate::mesh::ior_f0(ior as f32);
    }
    // clearcoat and clearcoatRoughness (values; UsdPreviewSurface's defaults 0 and 0.01).
    m.clearcoat = float("clearcoat", 0.0)?;
    m.clearcoat_roughness = float("clearcoatRoughness", 0.01)?;
    // emissiveColor: a value (UsdPreviewSurface's default: black), or a texture's colour.
    let emissive = property_path(path, &surface, "inputs:emissiveColor")?;
    match connected_output(path, stage, &emissive)? {
        Some((tex, _)) if info_id(path, stage, &tex)?.as_deref() == Some("UsdUVTexture") => {
            m.emission_texture = uv_texture(path, stage, &tex, uv_name, "emission")?;
            if m.emission_texture.is_some() {
                m.emission = [1.0; 3];
            }
        }
        Some((shader, _)) => warn(
            path,
            &format!("{material}: emissiveColor comes from {shader}, not a UsdUVTexture: not read"),
        ),
        None => {
            if let Some(c) = input_value(path, stage, &surface, "emissiveColor")?
                .as_ref()
                .and_then(vec3)
            {
                m.emission = [c.x as f32, c.y as f32, c.z as f32];
            }
        }
    }
    // opacity: a value (UsdPreviewSurface's default 1) lets rays through where below 1, as
    // Blender's importer makes it the Alpha (it also leaves opacityThreshold to a texture).
    let opacity = match input_value(path, stage, &surface, "opacity")? {
        Some(v) => scalar(&v).map_or(1.0, |x| x as f32),
        None => 1.0,
    };
    if opacity < 1.0 {
        (m.base_color[3], m.alpha_mode) = (opacity.max(0.0), AlphaMode::Blend);
    }
    // A texture replaces the input's value (the factor becomes 1), one channel of it (the
    // opacity's may be the alpha, `a`).
    for name in ["roughness", "metallic", "opacity"] {
        let input = property_path(path, &surface, &format!("inputs:{name}"))?;
        let Some((tex, output)) = connected_output(path, stage, &input)? else {
            continue;
        };
        if info_id(path, stage, &tex)?.as_deref() != Some("UsdUVTexture") {
            warn(
                path,
                &format!("{material}: {name} comes from {tex}, not a UsdUVTexture: not read"),
            );
            continue;
        }
        let channel = match output.as_str() {
            "r" => 0,
            "g" => 1,
            "b" => 2,
            "a" if name == "opacity" => 3,
            other => {
                warn(
                    path,
                    &format!(
                        "{material}: {name} reads output '{other}' of {tex}, not r, g or b: \
                         not read"
                    ),
                );
                continue;
            }
        };
        let Some(texture) = uv_texture(path, stage, &tex, uv_name, name)? else {
            continue;
        };
        let c = match channel {
            // The image's alpha channel, in all three of a texture of its own.
            3 => ChannelRef {
                texture: TextureRef {
                    color_space: ColorSpace::Alpha,
                    ..texture
                },
                channel: 0,
            },
            _ => ChannelRef { texture, channel },
        };
        match name {
            "roughness" => (m.roughness, m.roughness_texture) = (1.0, Some(c)),
            "metallic" => (m.metallic, m.metallic_texture) = (1.0, Some(c)),
            _ => {
                // Blender's importer: a textured opacity under an opacityThreshold above 0 is
                // cut at it (1 − (alpha < threshold)), else blended.
                let threshold = float("opacityThreshold", 0.0)?;
                m.base_color[3] = 1.0;
                m.alpha_mode = match threshold > 0.0 {
                    true => AlphaMode::Mask(threshold),
                    false => AlphaMode::Blend,
                };
                m.alpha_texture = Some(c);
            }
        }
    }
    m.normal_texture = normal_map(path, stage, &surface, &material, uv_name)?;
    Ok(Some((material, m)))
}

/// A `UsdPreviewSurface`'s `normal` input from a `UsdUVTexture`'s `rgb`: a tangent-space
/// normal map whose texel times the texture's `inputs:scale` plus its `inputs:bias` is the
/// normal, as UsdPreviewSurface specifies (exporters write scale 2 and bias −1 for a 0..1
/// image; without them the texels are the normal's components as they are, and a warning
/// says so).
fn normal_map(
    path: &Path,
    stage: &Stage,
    surface: &sdf::Path,
    material: &sdf::Path,
    uv_name: Option<&str>,
) -> Result<Option<NormalMapRef>> {
    let input = property_path(path, surface, "inputs:normal")?;
    let Some((tex, output)) = connected_output(path, stage, &input)? else {
        return Ok(None);
    };
    if info_id(path, stage, &tex)?.as_deref() != Some("UsdUVTexture") || output != "rgb" {
        warn(
            path,
            &format!(
                "{material}: normal comes from {tex} output '{output}', not a UsdUVTexture's \
                 rgb: not read"
            ),
        );
        return Ok(None);
    }
    let Some(texture) = uv_texture(path, stage, &tex, uv_name, "normal")? else {
        return Ok(None);
    };
    let (scale, bias) = texture_scale_bias(path, stage, &tex)?;
    if scale == [1.0; 3] && bias == [0.0; 3] {
        warn(
            path,
            &format!(
                "{tex}: the normal texture has no inputs:scale and inputs:bias: its texels are \
                 read as normals as they are (a 0..1 image wants scale (2, 2, 2, 1) and bias \
                 (-1, -1, -1, 0))"
            ),
        );
    }
    Ok(Some(NormalMapRef {
        texture,
        scale,
        bias,
        strength: 1.0,
    }))
}

/// A `UsdUVTexture` feeding a material's `what` input ("diffuse", "roughness", "metallic",
/// "normal", "emission"): its
/// file, wrap modes and colour space (`sourceColorSpace`: `raw`, `sRGB`, else `auto`); `None`
/// (with a warning) when it reads another UV primvar than the mesh's `uv_name` or has no file.
fn uv_texture(
    path: &Path,
    stage: &Stage,
    tex: &sdf::Path,
    uv_name: Option<&str>,
    what: &str,
) -> Result<Option<TextureRef>> {
    let Some(file) = texture_file(path, stage, tex)? else {
        warn(
            path,
            &format!("{tex}: the {what} texture has no inputs:file: not read"),
        );
        return Ok(None);
    };
    // `st` from a primvar reader, through any `UsdTransform2d`s (each maps its `in`).
    let mut transform = UvTransform::IDENTITY;
    let mut source = connected_output(path, stage, &property_path(path, tex, "inputs:st")?)?;
    let mut primvar = None;
    for _ in 0..32 {
        let Some((node, _)) = source else { break };
        if info_id(path, stage, &node)?.as_deref() != Some("UsdTransform2d") {
            primvar = token_input(path, stage, &node, "varname")?;
            break;
        }
        let float2 = |name: &str, default: [f32; 2]| -> Result<[f32; 2]> {
            Ok(typed_input(path, stage, &node, name, vec2, "float2")?.unwrap_or(default))
        };
        let rotation =
            typed_input(path, stage, &node, "rotation", scalar, "float")?.unwrap_or(0.0) as f32;
        let step = UvTransform::usd(
            float2("scale", [1.0; 2])?,
            rotation,
            float2("translation", [0.0; 2])?,
        );
        transform = transform.after(&step);
        source = connected_output(path, stage, &property_path(path, &node, "inputs:in")?)?;
    }
    if let (Some(p), Some(uv)) = (primvar.as_deref(), uv_name) {
        if p != uv {
            warn(
                path,
                &format!(
                    "{tex}: the {what} texture reads primvar '{p}', the mesh is loaded with \
                     '{uv}': not read (choose its UV set with --uv-set)"
                ),
            );
            return Ok(None);
        }
    }
    let wrap = |name: &str| -> Result<TexWrap> {
        Ok(match token_input(path, stage, tex, name)?.as_deref() {
            Some("clamp") | Some("black") => TexWrap::Clamp,
            Some("mirror") => TexWrap::Mirror,
            _ => TexWrap::Repeat,
        })
    };
    // `texel · scale + bias` per channel, applied when the texture is decoded; a normal map
    // applies its own (`normal_map`).
    let scale_bias = match what {
        "normal" => ([1.0; 3], [0.0; 3]),
        _ => texture_scale_bias(path, stage, tex)?,
    };
    Ok(Some(TextureRef {
        name: file.file_name().map_or_else(
            || file.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        ),
        data: TextureData::File(file),
        sampler: Sampler {
            wrap: [wrap("wrapS")?, wrap("wrapT")?],
            nearest: false,
        },
        // The mesh's own UV set (checked above): `Loader::material_index` sets it.
        tex_coord: 0,
        transform,
        color_space: match token_input(path, stage, tex, "sourceColorSpace")?.as_deref() {
            Some("raw") => ColorSpace::Raw,
            Some("sRGB") => ColorSpace::Srgb,
            _ => ColorSpace::Auto,
        },
        scale_bias: (scale_bias != ([1.0; 3], [0.0; 3])).then_some(scale_bias),
    }))
}

/// Input `name` of `shader` converted by `conv` (`want`: the type for the error, "float4"),
/// `None` where it is not authored; a value of another type is an error naming the input.
fn typed_input<T>(
    path: &Path,
    stage: &Stage,
    shader: &sdf::Path,
    name: &str,
    conv: fn(&Value) -> Option<T>,
    want: &str,
) -> Result<Option<T>> {
    match input_value(path, stage, shader, name)? {
        None => Ok(None),
        Some(v) => conv(&v).map(Some).ok_or_else(|| {
            prim_err(
                path,
                shader,
                format!("inputs:{name} is {}, expected {want}", kind(&v)),
            )
        }),
    }
}

/// A `UsdUVTexture`'s `inputs:scale` and `inputs:bias` for its r, g and b (1 and 0 where
/// unauthored).
fn texture_scale_bias(path: &Path, stage: &Stage, tex: &sdf::Path) -> Result<([f32; 3], [f32; 3])> {
    let rgb = |name: &str, default: f32| -> Result<[f32; 3]> {
        Ok(typed_input(path, stage, tex, name, vec4, "float4")?
            .map_or([default; 3], |v| [v[0] as f32, v[1] as f32, v[2] as f32]))
    };
    Ok((rgb("scale", 1.0)?, rgb("bias", 0.0)?))
}

/// A `UsdUVTexture`'s `inputs:file` (an asset path or a string), resolved; `None` when unset
/// or empty.
fn texture_file(path: &Path, stage: &Stage, tex: &sdf::Path) -> Result<Option<PathBuf>> {
    Ok(match input_value(path, stage, tex, "file")? {
        Some(Value::AssetPath(a)) if !a.asset_path().is_empty() => {
            Some(resolve_asset(path, stage, tex, "inputs:file", &a))
        }
        Some(Value::String(s)) if !s.is_empty() => Some(resolve_asset(
            path,
            stage,
            tex,
            "inputs:file",
            &sdf::AssetPath::new(s),
        )),
        _ => None,
    })
}

/// An asset path, resolved by openusd if it did, else relative to the layer that authored it.
fn resolve_asset(
    path: &Path,
    stage: &Stage,
    tex: &sdf::Path,
    property: &str,
    a: &sdf::AssetPath,
) -> PathBuf {
    if let Some(r) = a.resolved_path().filter(|r| !r.is_empty()) {
        return PathBuf::from(r);
    }
    let rel = PathBuf::from(a.asset_path());
    if rel.is_absolute() {
        return rel;
    }
    let layer_dir = property_path(path, tex, property)
        .ok()
        .and_then(|p| stage.attribute(p).property_stack().ok())
        .and_then(|s| s.into_iter().next())
        .map(|(layer, _)| PathBuf::from(layer))
        .filter(|l| l.is_file())
        .unwrap_or_else(|| path.to_path_buf());
    layer_dir.parent().unwrap_or(Path::new("")).join(rel)
}

#[cfg(test)]
#[path = "usd_tests.rs"]
mod tests;
