//! Random scenes (`assetfield synth --random SEED`): a room drawn from a seed, written as an
//! ordinary layout [`Script`] (so it can be saved as RON, read and rendered again).
//!
//! The draw, all from one SplitMix64 seed ([`assetfield_layout::rng::Rng`], no platform- or
//! version-dependent distributions):
//! - scene units per metre in `[0.5, 2)`: every length and position of the scene is
//!   multiplied by it (objects through their instance scale, floor and walls directly), and
//!   it is recorded as the script's `units_per_metre`;
//! - 3 to 12 object categories, each one asset, from the curated catalog models
//!   ([`crate::curated::CURATED`]) and the primitive assets of `scenes/assets/furniture.ron`
//!   and `scenes/assets/street.ron` (embedded in the binary), 2 to 5 instances each at
//!   varied yaw; table-top categories stand on tables (`Group(on: ...)`), only drawn when a
//!   table category was;
//! - some categories placed as touching pairs (two instances side by side, footprints in
//!   contact); the rest scattered with footprints kept clear (`Scatter`), so ground objects
//!   never overlap;
//! - a room sized to the footprints drawn (2.5-4x their area);
//! - a floor: none, a thin slab, a thick slab, a slab under part of the room only, or a
//!   patterned floor made of box tiles (checker, wood-like planks, carpet noise, asphalt
//!   noise); walls along 0 to 3 sides (low, so cameras see over them);
//! - cameras: the usual rig around the scene's bounds at 256 x 256 ([`RANDOM_RESOLUTION`]).

use crate::SynthError;
use crate::curated::{CURATED, CuratedModel, Placement, asset_name};
use assetfield_core::Rect2;
use assetfield_layout::resolve::asset_info_from_bounds;
use assetfield_layout::rng::Rng;
use assetfield_layout::script::{
    AssetDef, CaptureSettings, Item, ObjSource, Part, Region, Variation, ViewSettings,
};
use assetfield_layout::source::{parse_script, write_script};
use assetfield_layout::{AssetCatalog, AssetInfo, Script, load_str, resolve};
use glam::Vec2;
use std::collections::BTreeMap;
use std::path::Path;

/// Image size of random scenes unless `--res` says otherwise (pixels; what the mining
/// measurements of issue 16 use).
pub const RANDOM_RESOLUTION: u32 = 256;
/// Range of scene units per metre.
pub const UNITS_PER_METRE: (f32, f32) = (0.5, 2.0);
/// Range of the number of object categories (inclusive).
pub const CATEGORIES: (usize, usize) = (3, 12);
/// Range of instances per ground category (inclusive).
const INSTANCES: (usize, usize) = (2, 5);
/// Room area per unit of drawn footprint area (footprints padded by [`CLEARANCE`]).
const ROOM_FACTOR: (f32, f32) = (2.5, 4.0);
/// Gap kept around every footprint when sizing the room and between scattered objects
/// (metres): room to walk, and a few texels between objects on a trained plane.
const CLEARANCE: f32 = 0.3;
/// Smallest room side (metres).
const MIN_SIDE: f32 = 4.0;
/// Walls: thickness and height range (metres); low enough for cameras at 15 degrees to
/// see most of the floor over them.
const WALL_THICKNESS: f32 = 0.12;
const WALL_HEIGHT: (f32, f32) = (0.5, 1.1);
/// Times the room grows by [`GROW`] when the objects do not fit (scatter fails).
const ATTEMPTS: u32 = 8;
const GROW: f32 = 1.2;
/// Chance that a ground category is placed as a touching pair, and that a table carries
/// objects (when table-top categories exist).
const PAIR_CHANCE: f32 = 0.3;
const LOADED_TABLE_CHANCE: f32 = 0.6;

/// The built-in primitive asset files (shared with the scene suite).
const FURNITURE_RON: &str = include_str!("../../../scenes/assets/furniture.ron");
const STREET_RON: &str = include_str!("../../../scenes/assets/street.ron");

/// Where the primitive assets may stand (the rest of the two files: floor objects).
const PRIMITIVE_TABLES: [&str; 8] = [
    "table_rect",
    "table_round",
    "cafe_table",
    "desk",
    "student_desk",
    "coffee_table",
    "side_table",
    "bar_counter",
];
const PRIMITIVE_TABLE_TOPS: [&str; 3] = ["lamp", "monitor", "laptop"];

/// One asset a scene may draw.
#[derive(Debug, Clone)]
struct Candidate {
    name: String,
    def: AssetDef,
    info: AssetInfo,
    placement: Placement,
}

fn round3(v: f32) -> f32 {
    (v * 1000.0).round() / 1000.0
}

fn ceil3(v: f32) -> f32 {
    (v * 1000.0).ceil() / 1000.0
}

fn candidates() -> Result<Vec<Candidate>, SynthError> {
    let mut out = Vec::new();
    for (file, text) in [("furniture.ron", FURNITURE_RON), ("street.ron", STREET_RON)] {
        let s = parse_script(Path::new(file), text)?;
        for (name, def) in s.assets {
            if def.container {
                continue;
            }
            let placement = if PRIMITIVE_TABLES.contains(&name.as_str()) {
                Placement::Table
            } else if PRIMITIVE_TABLE_TOPS.contains(&name.as_str()) {
                Placement::TableTop
            } else {
                Placement::Floor
            };
            let info = asset_info_from_bounds(&name, &def, def.parts_bounds());
            out.push(Candidate { name, def, info, placement });
        }
    }
    for m in CURATED {
        out.push(curated_candidate(m));
    }
    Ok(out)
}

/// The asset of a curated model, with the footprint and height the synthesiser will give
/// it (the catalog size: depth along x, width along y).
fn curated_candidate(m: &CuratedModel) -> Candidate {
    let name = asset_name(m);
    let def = AssetDef {
        parts: Vec::new(),
        obj: Some(ObjSource::Catalog { name: m.catalog.to_string(), id: m.id.to_string() }),
        category: None,
        yaw_symmetry_deg: m.yaw_symmetry_deg,
        container: false,
        library: None,
    };
    let (w, d, h) = m.size_cm;
    let half = Vec2::new(d, w) / 200.0;
    let info = AssetInfo {
        category: name.clone(),
        footprint: Rect2::new(-half, half),
        outline: Vec::new(),
        height: h / 100.0,
        yaw_symmetry_deg: m.yaw_symmetry_deg,
        container: false,
        frame_yaw_deg: 0.0,
    };
    Candidate { name, def, info, placement: m.placement }
}

/// Resolution-time sizes of a drawn scene's assets (the synthesiser gives the same ones):
/// resolves a random scene without opening the furniture catalogs.
#[derive(Debug, Clone)]
pub struct DrawCatalog(BTreeMap<String, AssetInfo>);

impl AssetCatalog for DrawCatalog {
    fn asset_info(&self, name: &str) -> Option<AssetInfo> {
        self.0.get(name).cloned()
    }
    fn asset_names(&self) -> Vec<String> {
        self.0.keys().cloned().collect()
    }
}

/// Draw `k` distinct items of `pool` (in draw order).
fn pick<T: Clone>(rng: &mut Rng, pool: &[T], k: usize) -> Vec<T> {
    let mut idx: Vec<usize> = (0..pool.len()).collect();
    let mut out = Vec::new();
    for _ in 0..k.min(pool.len()) {
        let j = rng.below(idx.len());
        out.push(pool[idx.swap_remove(j)].clone());
    }
    out
}

fn int_in(rng: &mut Rng, lo: usize, hi: usize) -> usize {
    lo + rng.below(hi - lo + 1)
}

fn tile_box(center: (f32, f32, f32), size: (f32, f32, f32), color: (f32, f32, f32)) -> Part {
    Part::Box { center, size, color, yaw: 0.0 }
}

/// The floor's kind, as drawn (also the floor asset's name in the script).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum FloorKind {
    None,
    ThinSlab,
    ThickSlab,
    PartialSlab,
    Checker,
    Planks,
    Carpet,
    Asphalt,
}

impl FloorKind {
    /// The floors made of tiles (a pattern to match between photos).
    const TILED: [FloorKind; 4] =
        [FloorKind::Checker, FloorKind::Planks, FloorKind::Carpet, FloorKind::Asphalt];
    const ALL: [FloorKind; 8] = [
        FloorKind::None,
        FloorKind::ThinSlab,
        FloorKind::ThickSlab,
        FloorKind::PartialSlab,
        FloorKind::Checker,
        FloorKind::Planks,
        FloorKind::Carpet,
        FloorKind::Asphalt,
    ];
    fn name(self) -> &'static str {
        match self {
            FloorKind::None => "none",
            FloorKind::ThinSlab => "floor_thin",
            FloorKind::ThickSlab => "floor_thick",
            FloorKind::PartialSlab => "floor_partial",
            FloorKind::Checker => "floor_checker",
            FloorKind::Planks => "floor_planks",
            FloorKind::Carpet => "floor_carpet",
            FloorKind::Asphalt => "floor_asphalt",
        }
    }
}

/// Thin tiles (metres): thickness of a slab that only shows a colour or pattern.
const THIN: f32 = 0.02;

/// Floor parts in scene units over the room `[-hx, hx] x [-hy, hy]` (scene units, `u` per
/// metre).
fn floor_parts(rng: &mut Rng, kind: FloorKind, hx: f32, hy: f32, u: f32) -> Vec<Part> {
    let grey = |rng: &mut Rng, lo: f32, hi: f32| {
        let g = round3(rng.range(lo, hi));
        (g, g, round3(g * rng.range(0.95, 1.05)))
    };
    let slab = |t: f32, c| {
        tile_box((0.0, 0.0, round3(-0.5 * t)), (round3(2.0 * hx), round3(2.0 * hy), round3(t)), c)
    };
    match kind {
        FloorKind::None => Vec::new(),
        FloorKind::ThinSlab => vec![slab(THIN * u, grey(rng, 0.45, 0.8))],
        FloorKind::ThickSlab => vec![slab(rng.range(0.12, 0.3) * u, grey(rng, 0.4, 0.7))],
        FloorKind::PartialSlab => {
            let (fx, fy) = (rng.range(0.5, 0.85), rng.range(0.5, 0.85));
            let (sx, sy) = (2.0 * hx * fx, 2.0 * hy * fy);
            let cx = rng.range(-hx + 0.5 * sx, hx - 0.5 * sx);
            let cy = rng.range(-hy + 0.5 * sy, hy - 0.5 * sy);
            let t = THIN * u;
            vec![tile_box(
                (round3(cx), round3(cy), round3(-0.5 * t)),
                (round3(sx), round3(sy), round3(t)),
                grey(rng, 0.45, 0.75),
            )]
        }
        FloorKind::Checker | FloorKind::Carpet | FloorKind::Asphalt => {
            // square tiles: checker 0.5-1 m, noise 0.25-0.4 m
            let (lo, hi) = if kind == FloorKind::Checker { (0.5, 1.0) } else { (0.25, 0.4) };
            let tile = rng.range(lo, hi) * u;
            let (nx, ny) =
                (((2.0 * hx) / tile).ceil() as usize, ((2.0 * hy) / tile).ceil() as usize);
            let (tx, ty) = (2.0 * hx / nx as f32, 2.0 * hy / ny as f32);
            let a = grey(rng, 0.55, 0.9);
            let b = grey(rng, 0.15, 0.4);
            let base = match kind {
                FloorKind::Carpet => {
                    (rng.range(0.3, 0.7), rng.range(0.2, 0.5), rng.range(0.2, 0.6))
                }
                _ => grey(rng, 0.22, 0.35),
            };
            let t = THIN * u;
            let mut parts = Vec::with_capacity(nx * ny);
            for j in 0..ny {
                for i in 0..nx {
                    let c = match kind {
                        FloorKind::Checker => {
                            if (i + j) % 2 == 0 {
                                a
                            } else {
                                b
                            }
                        }
                        _ => {
                            let k = rng.range(0.85, 1.15);
                            (
                                round3((base.0 * k).min(1.0)),
                                round3((base.1 * k).min(1.0)),
                                round3((base.2 * k).min(1.0)),
                            )
                        }
                    };
                    let x = -hx + (i as f32 + 0.5) * tx;
                    let y = -hy + (j as f32 + 0.5) * ty;
                    parts.push(tile_box(
                        (round3(x), round3(y), round3(-0.5 * t)),
                        (round3(tx), round3(ty), round3(t)),
                        c,
                    ));
                }
            }
            parts
        }
        FloorKind::Planks => {
            // boards along x, 0.12-0.25 m wide, shades of brown
            let w = rng.range(0.12, 0.25) * u;
            let n = ((2.0 * hy) / w).ceil() as usize;
            let w = 2.0 * hy / n as f32;
            let t = THIN * u;
            let hue = (rng.range(0.45, 0.7), rng.range(0.28, 0.42), rng.range(0.12, 0.22));
            (0..n)
                .map(|j| {
                    let k = rng.range(0.8, 1.2);
                    let y = -hy + (j as f32 + 0.5) * w;
                    tile_box(
                        (0.0, round3(y), round3(-0.5 * t)),
                        (round3(2.0 * hx), round3(w), round3(t)),
                        (round3(hue.0 * k), round3(hue.1 * k), round3(hue.2 * k)),
                    )
                })
                .collect()
        }
    }
}

/// Walls along 0-3 sides of the room (scene units).
fn wall_parts(rng: &mut Rng, hx: f32, hy: f32, u: f32) -> Vec<Part> {
    let sides = rng.below(4);
    let h = rng.range(WALL_HEIGHT.0, WALL_HEIGHT.1) * u;
    let t = WALL_THICKNESS * u;
    let c =
        (round3(rng.range(0.7, 0.9)), round3(rng.range(0.68, 0.88)), round3(rng.range(0.65, 0.85)));
    // start at a random side, continue counter-clockwise (an L or a U)
    let first = rng.below(4);
    (0..sides)
        .map(|k| {
            let (center, size) = match (first + k) % 4 {
                0 => ((0.0, -hy - 0.5 * t), (2.0 * hx + 2.0 * t, t)),
                1 => ((hx + 0.5 * t, 0.0), (t, 2.0 * hy + 2.0 * t)),
                2 => ((0.0, hy + 0.5 * t), (2.0 * hx + 2.0 * t, t)),
                _ => ((-hx - 0.5 * t, 0.0), (t, 2.0 * hy + 2.0 * t)),
            };
            tile_box(
                (round3(center.0), round3(center.1), round3(0.5 * h)),
                (round3(size.0), round3(size.1), round3(h)),
                c,
            )
        })
        .collect()
}

/// A captured room's walls (metres): full height, so that the room is closed around the
/// walking cameras and only the sky shows over them.
const ROOM_HEIGHT: (f32, f32) = (2.4, 3.0);
/// The wallpaper's panels (metres, width and height ranges): a grid of panels in two shades
/// drawn at random, each a little off its shade, rows offset by half a panel as bricks are:
/// corners everywhere, what structure from motion matches between photos.
const PANEL_WIDTH: (f32, f32) = (0.25, 0.5);
const PANEL_HEIGHT: (f32, f32) = (0.15, 0.3);
/// Pictures per wall (inclusive range), their side (metres), the height of their centre
/// above the floor (metres) and how far they stand off the wall (metres, frame depth).
const PICTURES_PER_WALL: (usize, usize) = (2, 4);
const PICTURE_SIDE: (f32, f32) = (0.5, 1.2);
const PICTURE_HEIGHT: (f32, f32) = (1.2, 1.7);
const PICTURE_DEPTH: f32 = 0.03;
/// A picture's canvas: a grid of this many colour cells per side (inclusive range) inside a
/// frame of [`PICTURE_FRAME`] metres: corners for feature matching, as a painting has.
const PICTURE_CELLS: (usize, usize) = (3, 6);
const PICTURE_FRAME: f32 = 0.04;
/// The band between the furniture and a captured room's walls, metres: the walking path
/// lies in its middle ([`crate::capture::PATH_INSET_M`]).
const WALK_MARGIN: f32 = 1.0;

/// Which kind of scene a seed draws.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Style {
    /// Objects in a room seen from an orbit around it: low walls on 0-3 sides, any floor.
    Orbit,
    /// A room to photograph from inside (`synth --random SEED --capture`): walls all round
    /// at full height with wallpaper and pictures, a tiled floor, a walking margin between
    /// the furniture and the walls, and the capture rig in its `views`.
    Capture,
}

/// A captured room's walls on all four sides of `[-hx, hx] x [-hy, hy]` (scene units, `u`
/// per metre): panelled wallpaper and framed pictures on the inner faces.
fn capture_wall_parts(rng: &mut Rng, hx: f32, hy: f32, u: f32) -> Vec<Part> {
    let h = rng.range(ROOM_HEIGHT.0, ROOM_HEIGHT.1) * u;
    let t = WALL_THICKNESS * u;
    // a light shade and a darker one of about the same hue
    let light =
        (round3(rng.range(0.6, 0.92)), round3(rng.range(0.55, 0.9)), round3(rng.range(0.5, 0.88)));
    let k = rng.range(0.45, 0.65);
    let (a, b) = (light, (round3(light.0 * k), round3(light.1 * k), round3(light.2 * k)));
    let panel_w = rng.range(PANEL_WIDTH.0, PANEL_WIDTH.1) * u;
    let rows = ((h / (rng.range(PANEL_HEIGHT.0, PANEL_HEIGHT.1) * u)).round() as usize).max(1);
    let panel_h = h / rows as f32;
    let mut parts = Vec::new();
    for side in 0..4 {
        // `along`: half the wall's length; a box at (s along the wall, n off its inner face
        // towards the outside, z) of size (sa along, sn across, sz)
        let along = if side % 2 == 0 { hx + t } else { hy };
        let place = |s: f32, n: f32, z: f32, sa: f32, sn: f32, sz: f32, c| {
            let (center, size) = match side {
                0 => ((s, -hy - n), (sa, sn)),
                1 => ((hx + n, s), (sn, sa)),
                2 => ((-s, hy + n), (sa, sn)),
                _ => ((-hx - n, -s), (sn, sa)),
            };
            tile_box(
                (round3(center.0), round3(center.1), round3(z)),
                (round3(size.0), round3(size.1), round3(sz)),
                c,
            )
        };
        let n = ((2.0 * along) / panel_w).ceil().max(1.0) as usize;
        let w = 2.0 * along / n as f32;
        for row in 0..rows {
            // odd rows offset by half a panel: a half panel at each end
            let edges: Vec<f32> = if row % 2 == 0 {
                (0..=n).map(|k| -along + k as f32 * w).collect()
            } else {
                std::iter::once(-along)
                    .chain((0..n).map(|k| -along + (k as f32 + 0.5) * w))
                    .chain(std::iter::once(along))
                    .collect()
            };
            let z = (row as f32 + 0.5) * panel_h;
            for e in edges.windows(2) {
                let base = if rng.f32() < 0.5 { a } else { b };
                let j = rng.range(0.9, 1.1);
                let c = (round3(base.0 * j), round3(base.1 * j), round3(base.2 * j));
                parts.push(place(0.5 * (e[0] + e[1]), 0.5 * t, z, e[1] - e[0], t, panel_h, c));
            }
        }
        let count = int_in(rng, PICTURES_PER_WALL.0, PICTURES_PER_WALL.1);
        let slot = 2.0 * (along - t) / count as f32;
        for p in 0..count {
            let side_m = rng.range(PICTURE_SIDE.0, PICTURE_SIDE.1).min(0.8 * slot / u);
            let (pw, ph) = (side_m * u * rng.range(0.8, 1.25), side_m * u);
            let s = -(along - t) + (p as f32 + 0.5) * slot + rng.range(-0.1, 0.1) * slot;
            let z = rng.range(PICTURE_HEIGHT.0, PICTURE_HEIGHT.1) * u;
            let d = PICTURE_DEPTH * u;
            let dark = round3(rng.range(0.05, 0.3));
            parts.push(place(
                s,
                -0.5 * d,
                z,
                pw,
                d,
                ph,
                (dark, round3(dark * 0.9), round3(dark * 0.8)),
            ));
            let frame = PICTURE_FRAME * u;
            let (cw, ch) = (pw - 2.0 * frame, ph - 2.0 * frame);
            let (nx, ny) = (
                int_in(rng, PICTURE_CELLS.0, PICTURE_CELLS.1),
                int_in(rng, PICTURE_CELLS.0, PICTURE_CELLS.1),
            );
            for i in 0..nx {
                for j in 0..ny {
                    let c = (round3(rng.f32()), round3(rng.f32()), round3(rng.f32()));
                    let cs = s - 0.5 * cw + (i as f32 + 0.5) * cw / nx as f32;
                    let cz = z - 0.5 * ch + (j as f32 + 0.5) * ch / ny as f32;
                    // a hair in front of the frame's face
                    let cd = 0.1 * d;
                    parts.push(place(cs, -d - 0.5 * cd, cz, cw / nx as f32, cd, ch / ny as f32, c));
                }
            }
        }
    }
    parts
}

/// What a drawn scene holds, for reports and tests.
#[derive(Debug, Clone, PartialEq)]
pub struct RandomScene {
    pub seed: u64,
    pub script: Script,
    /// The script as RON (what `--write-script` and the dataset's `scene.ron` hold).
    pub text: String,
    pub units_per_metre: f32,
    pub floor: &'static str,
    /// Object categories (= assets) in draw order.
    pub categories: Vec<String>,
}

/// Draw the scene of `seed` (see the module docs). The same seed gives the same script, byte
/// for byte, on every machine.
pub fn random_scene(seed: u64) -> Result<RandomScene, SynthError> {
    random_scene_styled(seed, Style::Orbit)
}

/// Draw the scene of `seed` in a [`Style`]: [`random_scene`] for [`Style::Orbit`].
pub fn random_scene_styled(seed: u64, style: Style) -> Result<RandomScene, SynthError> {
    let pool = candidates()?;
    let mut last_err = None;
    for attempt in 0..ATTEMPTS {
        // GROW^attempt by multiplication (powi's rounding may vary by platform)
        let grow = (0..attempt).fold(1.0f32, |g, _| g * GROW);
        let scene = draw(seed, &pool, grow, style)?;
        // check that every scatter fits, with the sizes synthesis will use
        let loaded = load_str(Path::new(&format!("random_{seed}.ron")), &scene.text)?;
        match resolve(&loaded, &scene.catalog()?) {
            Ok(_) => return Ok(scene),
            Err(e) => last_err = Some(e),
        }
    }
    Err(SynthError::Config(format!(
        "random scene {seed}: the objects did not fit after {ATTEMPTS} attempts: {}",
        last_err.map(|e| e.to_string()).unwrap_or_default()
    )))
}

impl RandomScene {
    /// The sizes resolution needs, from the curated table and the primitives' parts.
    pub fn catalog(&self) -> Result<DrawCatalog, SynthError> {
        let pool = candidates()?;
        let infos = self
            .script
            .assets
            .iter()
            .map(|(n, d)| {
                let info = pool.iter().find(|c| &c.name == n).map(|c| c.info.clone());
                let info = info.unwrap_or_else(|| asset_info_from_bounds(n, d, d.parts_bounds()));
                (n.clone(), info)
            })
            .collect();
        Ok(DrawCatalog(infos))
    }
}

/// Draw random scene `seed` from `pool`, its room grown by `grow` (in area, squared): the
/// categories, the room and its container, touching pairs, scatters, objects on tables and
/// spare categories, in that order. Every step draws from one generator in a fixed order,
/// so a seed gives the same scene on every machine.
fn draw(seed: u64, pool: &[Candidate], grow: f32, style: Style) -> Result<RandomScene, SynthError> {
    let mut rng = Rng::stream(seed, "random-scene");
    let u = round3(rng.range(UNITS_PER_METRE.0, UNITS_PER_METRE.1));
    let picked = Picked::draw(&mut rng, pool);
    let counts: Vec<usize> =
        picked.ground.iter().map(|_| int_in(&mut rng, INSTANCES.0, INSTANCES.1)).collect();
    let (hx, hy) = room_half_sides(&mut rng, &picked.ground, &counts, grow, u);
    let mut d = Drawing {
        seed,
        rng,
        u,
        hx,
        hy,
        style,
        assets: BTreeMap::new(),
        layout: Vec::new(),
        taken: Vec::new(),
    };
    let floor = d.container();
    let paired: Vec<bool> = picked.ground.iter().map(|c| d.pair(c)).collect();
    let mut table_keys: Vec<(String, Candidate, usize)> = Vec::new();
    for (ci, (c, &n)) in picked.ground.iter().zip(&counts).enumerate() {
        let rest = if paired[ci] { n.saturating_sub(2) } else { n };
        if rest == 0 {
            continue;
        }
        let key = d.scatter(ci, c, rest, paired[ci]);
        if c.placement == Placement::Table {
            table_keys.push((key, c.clone(), rest));
        }
    }
    let used_tops = d.table_tops(&table_keys, &picked.tops);
    let mut categories: Vec<String> = picked.ground.iter().map(|c| c.name.clone()).collect();
    categories.extend(used_tops);
    categories.extend(d.spare_categories(&picked.floors, categories.len()));
    let Drawing { assets, layout, .. } = d;
    let (name, room, capture) = match style {
        Style::Orbit => (format!("random_{seed}"), (hx, hy), None),
        Style::Capture => {
            let m = round3(WALK_MARGIN * u);
            let settings = CaptureSettings { seed: Some(seed), ..Default::default() };
            (format!("capture_{seed}"), (round3(hx + m), round3(hy + m)), Some(settings))
        }
    };
    let script = Script {
        name: Some(name),
        assets,
        extent: Some(((-room.0, -room.1), room)),
        views: Some(ViewSettings {
            count: None,
            test: None,
            resolution: Some(RANDOM_RESOLUTION),
            radius: None,
            elevation_deg: None,
            fov_deg: None,
            capture,
        }),
        units_per_metre: Some(u),
        layout,
        ..Script::default()
    };
    let body = write_script(&script)?;
    let flag = if style == Style::Capture { " --capture" } else { "" };
    let text = format!(
        "// Random scene {seed} drawn by `assetfield synth --random {seed}{flag}` ({} categories, floor: {}, {:.3} scene units per metre).\n// Rendering this file gives the same dataset: assetfield synth THIS_FILE\n{body}",
        categories.len(),
        floor.name(),
        u
    );
    Ok(RandomScene { seed, script, text, units_per_metre: u, floor: floor.name(), categories })
}

/// The categories of a scene: those standing on the ground (tables first), the table-top
/// categories (only with tables), and the pool's floor categories (for spares).
struct Picked {
    ground: Vec<Candidate>,
    tops: Vec<Candidate>,
    floors: Vec<Candidate>,
}

impl Picked {
    fn draw(rng: &mut Rng, pool: &[Candidate]) -> Self {
        let k = int_in(rng, CATEGORIES.0, CATEGORIES.1);
        let of =
            |p: Placement| pool.iter().filter(|c| c.placement == p).cloned().collect::<Vec<_>>();
        let (floors, tables, tops) =
            (of(Placement::Floor), of(Placement::Table), of(Placement::TableTop));
        // tables in 7 of 10 scenes; table-top categories only with tables
        let n_tables = if rng.f32() < 0.7 { 1 + rng.below(2) } else { 0 };
        let n_tops =
            if n_tables > 0 { rng.below(3).min(k.saturating_sub(n_tables + 1)) } else { 0 };
        let n_floor = k - n_tables - n_tops;
        let mut ground: Vec<Candidate> = pick(rng, &tables, n_tables);
        ground.extend(pick(rng, &floors, n_floor));
        let tops = pick(rng, &tops, n_tops);
        Picked { ground, tops, floors }
    }
}

/// Half the room's sides in scene units: its area the padded footprints of every instance
/// times a drawn factor (and `grow` squared), its aspect drawn, no side under [`MIN_SIDE`].
fn room_half_sides(
    rng: &mut Rng,
    ground: &[Candidate],
    counts: &[usize],
    grow: f32,
    u: f32,
) -> (f32, f32) {
    let area: f32 = ground
        .iter()
        .zip(counts)
        .map(|(c, &n)| {
            let s = c.info.footprint.size() + Vec2::splat(CLEARANCE);
            n as f32 * s.x * s.y
        })
        .sum();
    let room_area = area * rng.range(ROOM_FACTOR.0, ROOM_FACTOR.1) * grow * grow;
    let aspect = rng.range(0.7, 1.4);
    let sx = (room_area * aspect).sqrt().max(MIN_SIDE);
    let sy = (room_area / aspect).sqrt().max(MIN_SIDE);
    (round3(0.5 * sx * u), round3(0.5 * sy * u))
}

/// A random scene being drawn: the generator, the scale and the room, and the assets and
/// layout items drawn so far.
struct Drawing {
    seed: u64,
    rng: Rng,
    /// Scene units per metre.
    u: f32,
    /// Half the room's sides, scene units.
    hx: f32,
    hy: f32,
    assets: BTreeMap<String, AssetDef>,
    layout: Vec<Item>,
    /// The boxes of the touching pairs placed so far (scatters keep clear by themselves).
    taken: Vec<Rect2>,
    style: Style,
}

impl Drawing {
    /// Half the region a category's instances may stand in: the room less the instance's
    /// half diagonal and the clearance.
    fn inner(&self, c: &Candidate) -> (f32, f32) {
        let r = 0.5 * c.info.footprint.size().length() * self.u + CLEARANCE * self.u;
        (self.hx - r, self.hy - r)
    }

    /// The floor and walls, as one container instance named `room` (where there is either).
    fn container(&mut self) -> FloorKind {
        let (hx, hy, u) = (self.hx, self.hy, self.u);
        let (floor, mut container_parts, walls) = match self.style {
            Style::Orbit => {
                let floor = FloorKind::ALL[self.rng.below(FloorKind::ALL.len())];
                let parts = floor_parts(&mut self.rng, floor, hx, hy, u);
                (floor, parts, wall_parts(&mut self.rng, hx, hy, u))
            }
            Style::Capture => {
                // a floor with texture for structure from motion, under the walking margin too
                let floor = FloorKind::TILED[self.rng.below(FloorKind::TILED.len())];
                let m = WALK_MARGIN * u;
                let (rx, ry) = (round3(hx + m), round3(hy + m));
                let parts = floor_parts(&mut self.rng, floor, rx, ry, u);
                (floor, parts, capture_wall_parts(&mut self.rng, rx, ry, u))
            }
        };
        let has_walls = !walls.is_empty();
        if !container_parts.is_empty() || has_walls {
            let name = if container_parts.is_empty() { "walls" } else { floor.name() };
            container_parts.extend(walls);
            self.assets.insert(
                name.to_string(),
                AssetDef {
                    parts: container_parts,
                    obj: None,
                    category: None,
                    yaw_symmetry_deg: 360.0,
                    container: true,
                    library: None,
                },
            );
            self.layout.push(Item::Instance {
                asset: name.to_string(),
                at: (0.0, 0.0),
                yaw: 0.0,
                scale: 1.0,
                base: 0.0,
                name: Some("room".into()),
            });
        }
        floor
    }

    /// Add category `c`, and by chance (floor categories only) two of its instances side by
    /// side, in contact, clear of the pairs placed before: whether the pair was placed.
    fn pair(&mut self, c: &Candidate) -> bool {
        self.assets.insert(c.name.clone(), c.def.clone());
        let (ix, iy) = self.inner(c);
        let (hx, hy, u) = (self.hx, self.hy, self.u);
        let pair =
            c.placement == Placement::Floor && self.rng.f32() < PAIR_CHANCE && ix > 0.0 && iy > 0.0;
        if !pair {
            return false;
        }
        // side by side along local y, turned by a multiple of 90 degrees
        let quarter = self.rng.below(4);
        let fp = c.info.footprint.size();
        let (w, d) = (fp.y, fp.x);
        let half =
            if quarter.is_multiple_of(2) { Vec2::new(0.5 * d, w) } else { Vec2::new(w, 0.5 * d) }
                * u;
        for _ in 0..50 {
            let p = Vec2::new(self.rng.range(-ix, ix), self.rng.range(-iy, iy));
            let pad = Vec2::splat(CLEARANCE * u);
            let r = Rect2::new(p - half - pad, p + half + pad);
            if r.min.x < -hx || r.min.y < -hy || r.max.x > hx || r.max.y > hy {
                continue;
            }
            if self.taken.iter().any(|t| !t.intersection(&r).is_empty()) {
                continue;
            }
            self.taken.push(r);
            self.layout.push(Item::Group {
                name: Some(format!("{}_pair", c.name)),
                at: (round3(p.x), round3(p.y)),
                yaw: 90.0 * quarter as f32,
                scale: u,
                base: 0.0,
                on: None,
                around: None,
                children: vec![Item::Row {
                    asset: c.name.clone(),
                    // rounded up to the millimetre: in contact, never overlapping
                    from: (0.0, -ceil3(0.5 * w)),
                    to: (0.0, ceil3(0.5 * w)),
                    count: 2,
                    yaw: 0.0,
                    face: Default::default(),
                    scale: 1.0,
                    vary: None,
                    name: Some(format!("{}s", c.name)),
                }],
            });
            return true;
        }
        false
    }

    /// `rest` instances of category `ci` scattered over the room, clear of everything placed
    /// before them, turned freely or by quarter turns with jitter: the scatter's name.
    fn scatter(&mut self, ci: usize, c: &Candidate, rest: usize, after_pair: bool) -> String {
        let seed = self.seed;
        let (ix, iy) = self.inner(c);
        let diag = c.info.footprint.size().length();
        let yaw_rule = if self.rng.f32() < 0.5 {
            Variation {
                yaw_jitter_deg: 180.0,
                seed: seed.wrapping_add(ci as u64),
                ..Default::default()
            }
        } else {
            Variation {
                yaw_choices: vec![0.0, 90.0, 180.0, 270.0],
                yaw_jitter_deg: round3(self.rng.range(0.0, 20.0)),
                seed: seed.wrapping_add(ci as u64),
                ..Default::default()
            }
        };
        let name = if after_pair { format!("{}_more", c.name) } else { format!("{}s", c.name) };
        self.layout.push(Item::Scatter {
            asset: c.name.clone(),
            region: Region::Rect { min: (round3(-ix), round3(-iy)), max: (round3(ix), round3(iy)) },
            count: rest as u32,
            min_distance: round3((0.5 * diag + CLEARANCE) * self.u),
            seed: seed.wrapping_mul(31).wrapping_add(ci as u64),
            yaw: 0.0,
            scale: self.u,
            overlap: false,
            vary: Some(yaw_rule),
            name: Some(name.clone()),
        });
        name
    }

    /// Objects on tables: one or two per loaded table, in the table's own (unscaled) frame;
    /// every table-top category is used first (where it fits), then tables are loaded by
    /// chance. `table_keys`: each table scatter's name, category and count. The table-top
    /// categories used.
    fn table_tops(
        &mut self,
        table_keys: &[(String, Candidate, usize)],
        top_cats: &[Candidate],
    ) -> Vec<String> {
        let mut unused: Vec<Candidate> = top_cats.to_vec();
        let mut used_tops: Vec<String> = Vec::new();
        for (key, table, n) in table_keys {
            for t in 0..*n {
                if top_cats.is_empty()
                    || (unused.is_empty() && self.rng.f32() >= LOADED_TABLE_CHANCE)
                {
                    continue;
                }
                let tf = table.info.footprint;
                let fits = |c: &Candidate| {
                    let room = tf.size() - Vec2::splat(c.info.footprint.size().length());
                    room.x > 0.0 && room.y > 0.0
                };
                let top = match unused.iter().position(&fits) {
                    Some(j) => unused.remove(j),
                    None => {
                        let fitting: Vec<&Candidate> =
                            top_cats.iter().filter(|c| fits(c)).collect();
                        if fitting.is_empty() {
                            continue;
                        }
                        fitting[self.rng.below(fitting.len())].clone()
                    }
                };
                self.assets.insert(top.name.clone(), top.def.clone());
                if !used_tops.contains(&top.name) {
                    used_tops.push(top.name.clone());
                }
                let children = self.on_top(&top, tf);
                self.layout.push(Item::standing_on(format!("{key}[{t}]"), children));
            }
        }
        used_tops
    }

    /// One instance of `top` anywhere on a table top of footprint `tf`, or two on the halves
    /// of its longer side.
    fn on_top(&mut self, top: &Candidate, tf: Rect2) -> Vec<Item> {
        let of = top.info.footprint.size().length();
        let room = tf.size() - Vec2::splat(of);
        let two = self.rng.f32() < 0.4 && room.x.max(room.y) > 2.0 * of;
        let along_x = tf.size().x >= tf.size().y;
        let (lo, hi) = (tf.center() - 0.5 * room, tf.center() + 0.5 * room);
        let spans: Vec<(Vec2, Vec2)> = if !two {
            vec![(lo, hi)]
        } else if along_x {
            let mid = tf.center().x;
            vec![(lo, Vec2::new(mid - 0.5 * of, hi.y)), (Vec2::new(mid + 0.5 * of, lo.y), hi)]
        } else {
            let mid = tf.center().y;
            vec![(lo, Vec2::new(hi.x, mid - 0.5 * of)), (Vec2::new(lo.x, mid + 0.5 * of), hi)]
        };
        spans
            .iter()
            .enumerate()
            .map(|(half, (a, b))| Item::Instance {
                asset: top.name.clone(),
                at: (
                    round3(self.rng.range(a.x, b.x.max(a.x))),
                    round3(self.rng.range(a.y, b.y.max(a.y))),
                ),
                yaw: round3(self.rng.range(-180.0, 180.0)),
                scale: 1.0,
                base: 0.0,
                name: Some(format!("{}_{half}", top.name)),
            })
            .collect()
    }

    /// Floor categories in place of the table-top categories that found no table, up to the
    /// fewest categories a scene has (`have`: the categories so far): their names.
    fn spare_categories(&mut self, floors: &[Candidate], have: usize) -> Vec<String> {
        let spare: Vec<Candidate> =
            floors.iter().filter(|c| !self.assets.contains_key(&c.name)).cloned().collect();
        let extra = pick(&mut self.rng, &spare, CATEGORIES.0.saturating_sub(have));
        let seed = self.seed;
        for (j, c) in extra.iter().enumerate() {
            let (ix, iy) = self.inner(c);
            self.assets.insert(c.name.clone(), c.def.clone());
            self.layout.push(Item::Scatter {
                asset: c.name.clone(),
                region: Region::Rect {
                    min: (round3(-ix), round3(-iy)),
                    max: (round3(ix), round3(iy)),
                },
                count: INSTANCES.0 as u32,
                min_distance: round3((0.5 * c.info.footprint.size().length() + CLEARANCE) * self.u),
                seed: seed.wrapping_mul(37).wrapping_add(j as u64),
                yaw: 0.0,
                scale: self.u,
                overlap: false,
                vary: Some(Variation {
                    yaw_jitter_deg: 180.0,
                    seed: seed.wrapping_add(100 + j as u64),
                    ..Default::default()
                }),
                name: Some(format!("{}s", c.name)),
            });
        }
        extra.iter().map(|c| c.name.clone()).collect()
    }
}
