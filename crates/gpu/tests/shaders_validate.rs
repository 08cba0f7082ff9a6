//! Every WGSL shader under `crates/` parses and validates with naga (the version wgpu uses),
//! and the render shader's header matches what the host uploads. Needs no GPU.

mod common;

use assetfield_field::{DecoderKind, ModelKind};
use assetfield_gpu::{
    RASTER_WGSL, RENDER_WGSL, occupancy_pass_members, plan_upload, raster_struct_members,
};
use naga::valid::{Capabilities, ValidationFlags, Validator};
use naga::{ArraySize, Handle, Module, Type, TypeInner};
use std::path::{Path, PathBuf};

fn wgsl_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            if path
                .file_name()
                .is_some_and(|n| n != "target" && !n.to_string_lossy().starts_with('.'))
            {
                wgsl_files(&path, out);
            }
        } else if path.extension().is_some_and(|e| e == "wgsl") {
            out.push(path);
        }
    }
}

fn validate(source: &str, name: &str) -> Result<Module, String> {
    let module = naga::front::wgsl::parse_str(source)
        .map_err(|e| e.emit_to_string_with_path(source, name))?;
    Validator::new(ValidationFlags::all(), Capabilities::default())
        .validate(&module)
        .map_err(|e| e.emit_to_string_with_path(source, name))?;
    Ok(module)
}

#[test]
fn every_wgsl_file_validates() {
    let crates = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut files = Vec::new();
    wgsl_files(&crates, &mut files);
    files.sort();
    for name in ["render.wgsl", "raster.wgsl"] {
        assert!(
            files.iter().any(|f| f.ends_with(format!("gpu/src/{name}"))),
            "{name} not found among {files:?}"
        );
    }
    let mut failed = Vec::new();
    for f in &files {
        let source = std::fs::read_to_string(f).unwrap();
        match validate(&source, &f.display().to_string()) {
            Ok(_) => eprintln!("ok: {}", f.display()),
            Err(e) => failed.push(e),
        }
    }
    assert!(failed.is_empty(), "{} shader(s) failed:\n{}", failed.len(), failed.join("\n"));
}

/// Scalar members of `ty` with their byte offsets, named as `a.b[2].c`.
fn flatten(
    module: &Module,
    ty: Handle<Type>,
    offset: u32,
    name: &str,
    out: &mut Vec<(String, u32)>,
) {
    match &module.types[ty].inner {
        TypeInner::Struct { members, .. } => {
            for m in members {
                let n = m.name.clone().unwrap();
                let n = if name.is_empty() { n } else { format!("{name}.{n}") };
                flatten(module, m.ty, offset + m.offset, &n, out);
            }
        }
        TypeInner::Array { base, size: ArraySize::Constant(len), stride } => {
            for i in 0..len.get() {
                flatten(module, *base, offset + i * stride, &format!("{name}[{i}]"), out);
            }
        }
        TypeInner::Scalar(s) => {
            assert_eq!(s.width, 4, "{name}");
            out.push((name.to_string(), offset));
        }
        other => panic!("{name}: unexpected type {other:?} in the header"),
    }
}

#[test]
fn the_header_layout_matches_the_host() {
    let module = validate(RENDER_WGSL, "render.wgsl").unwrap();
    let (ty, _) = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some("Header"))
        .expect("struct Header");
    let mut members = Vec::new();
    flatten(&module, ty, 0, "", &mut members);
    let TypeInner::Struct { span, .. } = module.types[ty].inner else { unreachable!() };
    for (kind, decoder) in [
        (ModelKind::Standard, DecoderKind::Mlp { hidden: vec![64], view_freqs: 2 }),
        (ModelKind::Integrated, DecoderKind::Sh { degree: 2 }),
        (ModelKind::Vm, DecoderKind::Mlp { hidden: vec![32, 32], view_freqs: 1 }),
    ] {
        let field = common::structured_field(kind, decoder);
        let occ = common::occupancy(&field);
        let plan = plan_upload(&field, Some(&occ), &wgpu::Limits::default()).unwrap();
        let host: Vec<(String, u32)> =
            plan.header.iter().enumerate().map(|(k, f)| (f.name.clone(), 4 * k as u32)).collect();
        assert_eq!(host, members, "{kind:?}: host header vs render.wgsl's Header");
        assert_eq!(span, 4 * plan.header.len() as u32);
    }
}

/// The raster shader's structs (`Raster`, `Chunk`, `Inst`) and the occupancy pass's
/// `OccPass` (in `render.wgsl`) match the words the host packs: member for member, one
/// 32-bit word each, nothing after the last.
#[test]
fn the_raster_structs_match_the_host() {
    let raster = validate(RASTER_WGSL, "raster.wgsl").unwrap();
    let render = validate(RENDER_WGSL, "render.wgsl").unwrap();
    let structs = raster_struct_members()
        .into_iter()
        .map(|(name, host)| (&raster, name, host))
        .chain([(&render, "OccPass", occupancy_pass_members())]);
    for (module, name, host) in structs {
        let (ty, _) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("struct {name} in the shaders"));
        let mut members = Vec::new();
        flatten(module, ty, 0, "", &mut members);
        let host: Vec<(String, u32)> =
            host.iter().enumerate().map(|(k, n)| (n.to_string(), 4 * k as u32)).collect();
        assert_eq!(host, members, "host words vs the shader's {name}");
        let TypeInner::Struct { span, .. } = module.types[ty].inner else { unreachable!() };
        assert_eq!(span, 4 * host.len() as u32, "{name}");
    }
}
