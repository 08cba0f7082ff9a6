//! The catalog models chosen as free-standing objects for generated scenes.
//!
//! Rules (checked against the catalogs by `crates/synth/tests/catalog.rs`): a model is kept
//! only if it stands on the floor or on a table by itself: no doors, windows or their parts
//! (`doorOrWindow`, category "Doors and windows"), nothing wall-mounted or hanging (any
//! `elevation` > 0: radiators, wall lamps, ceiling lights, hanging clothes), no ceiling or
//! track lights, nothing flat enough to read as floor (rugs, mats, sidewalks), nothing
//! fixed to a building (`movable=false`: columns, benches cast in concrete, bathroom
//! fittings), no people or animals (not furniture), and no vehicles (they dwarf a room and
//! the street scenes already have cars). Table-top objects must be at least 8 cm in every
//! ground direction and 5 cm high: smaller ones (forks, pens, glasses) are a few texels on
//! a trained plane and tell nothing about mining. Floor objects are furniture and plants
//! between 30 cm and 2.3 m tall with a footprint under 2.2 m.

/// Where a curated model may stand in a generated scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Placement {
    /// On the floor (chairs, sofas, shelves, plants, floor lamps).
    Floor,
    /// On the floor, and other objects may stand on it (tables, desks).
    Table,
    /// On a table (lamps, laptops, small plants, boxes).
    TableTop,
}

/// One curated model: its catalog, id, where it stands, and the turn after which it looks
/// the same (360 = none, 0 = round), as for `Asset(yaw_symmetry_deg: ...)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CuratedModel {
    pub catalog: &'static str,
    pub id: &'static str,
    pub placement: Placement,
    pub yaw_symmetry_deg: f32,
    /// Catalog size (width, depth, height) in centimetres, as the index gives it: lets a
    /// scene be drawn without opening the catalogs (the tests check it against them).
    pub size_cm: (f32, f32, f32),
}

const fn m(
    catalog: &'static str,
    id: &'static str,
    placement: Placement,
    yaw_symmetry_deg: f32,
    size_cm: (f32, f32, f32),
) -> CuratedModel {
    CuratedModel { catalog, id, placement, yaw_symmetry_deg, size_cm }
}

const BS: &str = "BlendSwap-CC-BY";
const KL: &str = "KatorLegaz";
use Placement::{Floor, Table, TableTop};

/// The curated models, in a fixed order (generated scenes index into it).
pub const CURATED: &[CuratedModel] = &[
    // Kator Legaz
    m(KL, "Kator Legaz#cafe-chair", Floor, 360.0, (49.5, 51.7, 85.0)),
    m(KL, "Kator Legaz#cafe-table", Table, 0.0, (74.2, 74.2, 70.0)),
    m(KL, "Kator Legaz#painted-bench", Floor, 360.0, (142.6, 51.8, 80.0)),
    m(KL, "Kator Legaz#residential-trashcan", Floor, 0.0, (58.6, 58.6, 80.0)),
    m(KL, "Kator Legaz#bullet-trash-can", Floor, 0.0, (33.0, 33.0, 74.0)),
    m(KL, "Kator Legaz#pedestal-vase-lamp", Floor, 0.0, (28.2, 28.2, 80.0)),
    m(KL, "Kator Legaz#mid-century-chair", Floor, 360.0, (73.5, 84.4, 80.0)),
    m(KL, "Kator Legaz#bar-stool", Floor, 360.0, (53.2, 59.3, 110.0)),
    m(KL, "Kator Legaz#bench", Floor, 180.0, (118.2, 45.2, 45.0)),
    m(KL, "Kator Legaz#dining-chair", Floor, 360.0, (42.3, 57.3, 100.0)),
    m(KL, "Kator Legaz#folding-table", Table, 180.0, (186.0, 77.6, 75.0)),
    m(KL, "Kator Legaz#glass-dining-table", Table, 180.0, (161.8, 97.6, 75.0)),
    m(KL, "Kator Legaz#utility-shelving", Floor, 360.0, (60.0, 30.0, 120.0)),
    m(KL, "Kator Legaz#mid-century-sofa", Floor, 360.0, (199.0, 84.0, 80.0)),
    m(KL, "Kator Legaz#office-chair", Floor, 360.0, (64.3, 64.3, 91.0)),
    m(KL, "Kator Legaz#filing-cabinet", Floor, 360.0, (38.6, 52.6, 60.0)),
    m(KL, "Kator Legaz#fire-hydrant", Floor, 360.0, (41.4, 33.3, 76.4)),
    m(KL, "Kator Legaz#full-bookcase", Floor, 360.0, (89.8, 34.7, 221.0)),
    m(KL, "Kator Legaz#trunk-large", Floor, 180.0, (100.0, 50.8, 34.4)),
    m(KL, "Kator Legaz#coffee-maker", TableTop, 360.0, (18.6, 28.7, 30.0)),
    m(KL, "Kator Legaz#apple-imac-1998", TableTop, 360.0, (42.5, 50.0, 40.1)),
    m(KL, "Kator Legaz#apple-ibook-2001", TableTop, 360.0, (28.5, 27.2, 22.9)),
    m(KL, "Kator Legaz#bowl", TableTop, 180.0, (44.8, 35.0, 17.0)),
    m(KL, "Kator Legaz#recycling-bin", TableTop, 180.0, (36.1, 27.0, 25.49968)),
    // Blend Swap (CC-BY)
    m(BS, "Blend Swap CC-BY#bedsideTable", Floor, 360.0, (50.0, 41.4, 48.0)),
    m(BS, "Blend Swap CC-BY#biurko3", Table, 360.0, (120.1, 60.2, 72.0)),
    m(BS, "Blend Swap CC-BY#cafe_set_mota_chair", Floor, 360.0, (60.9, 55.8, 78.3)),
    m(BS, "Blend Swap CC-BY#cafe_set_mota_table", Table, 0.0, (62.2, 62.2, 74.0)),
    m(BS, "Blend Swap CC-BY#cafe_set_tonon_chair", Floor, 360.0, (48.0, 53.3, 82.2)),
    m(BS, "Blend Swap CC-BY#chairWithCushion", Floor, 360.0, (42.3, 44.6, 91.1)),
    m(BS, "Blend Swap CC-BY#coffeeTable", Table, 180.0, (120.0, 70.1, 45.0)),
    m(BS, "Blend Swap CC-BY#ella_chair_f", Floor, 360.0, (46.0, 57.0, 92.0)),
    m(BS, "Blend Swap CC-BY#green_stool", Floor, 0.0, (42.9, 42.9, 46.0)),
    m(BS, "Blend Swap CC-BY#leaf_chair", Floor, 360.0, (67.1, 81.3, 82.65)),
    m(BS, "Blend Swap CC-BY#simpleDesk", Table, 360.0, (140.1, 81.1, 72.0)),
    m(BS, "Blend Swap CC-BY#table", Table, 180.0, (144.3, 93.4, 72.4)),
    m(BS, "Blend Swap CC-BY#mediumIndoorPlant", Floor, 0.0, (72.5, 76.6, 67.9)),
    m(BS, "Blend Swap CC-BY#sofa2", Floor, 360.0, (177.0, 86.1, 78.0)),
    m(BS, "Blend Swap CC-BY#spatifilum", Floor, 0.0, (79.8, 74.9, 87.5)),
    m(BS, "Blend Swap CC-BY#tvStand", Floor, 360.0, (135.1, 46.5, 52.6)),
    m(BS, "Blend Swap CC-BY#yuccaPlant", Floor, 0.0, (107.9, 102.4, 180.0)),
    m(BS, "Blend Swap CC-BY#armchair1", Floor, 360.0, (100.5, 88.2, 80.0)),
    m(BS, "Blend Swap CC-BY#decorativePlant", Floor, 0.0, (31.8, 32.2, 60.6)),
    m(BS, "Blend Swap CC-BY#fotel", Floor, 360.0, (73.5, 61.1, 69.7)),
    m(BS, "Blend Swap CC-BY#classSeat", Floor, 360.0, (62.5, 67.7, 80.0)),
    m(BS, "Blend Swap CC-BY#foldingChair", Floor, 360.0, (50.8, 60.0, 91.2)),
    m(BS, "Blend Swap CC-BY#plaidChair", Floor, 360.0, (40.5, 42.6, 80.0)),
    m(BS, "Blend Swap CC-BY#sofa3", Floor, 360.0, (204.2, 76.9, 80.0)),
    m(BS, "Blend Swap CC-BY#armChair2", Floor, 360.0, (97.8, 82.1, 88.5)),
    m(BS, "Blend Swap CC-BY#bookcase", Floor, 360.0, (166.4, 33.1, 186.4)),
    m(BS, "Blend Swap CC-BY#kitchenChair", Floor, 360.0, (43.0, 44.0, 91.0)),
    m(BS, "Blend Swap CC-BY#chair3", Floor, 360.0, (43.3, 50.4, 90.6)),
    m(BS, "Blend Swap CC-BY#chair4", Floor, 360.0, (55.8, 60.8, 90.5)),
    m(BS, "Blend Swap CC-BY#couch3", Floor, 360.0, (201.0, 90.9, 84.3)),
    m(BS, "Blend Swap CC-BY#dresserWithDrawers", Floor, 360.0, (160.5, 51.9, 81.0)),
    m(BS, "Blend Swap CC-BY#chest", Floor, 360.0, (143.5, 53.6, 82.0)),
    m(BS, "Blend Swap CC-BY#lamp", TableTop, 0.0, (30.5, 30.5, 40.9)),
    m(BS, "Blend Swap CC-BY#laptop", TableTop, 360.0, (33.9, 25.3, 26.6)),
    m(BS, "Blend Swap CC-BY#campingLamp", TableTop, 0.0, (15.4, 15.4, 36.7)),
    m(BS, "Blend Swap CC-BY#arbolito", TableTop, 0.0, (25.4, 26.2, 38.0)),
    m(BS, "Blend Swap CC-BY#luckyBamboo", TableTop, 0.0, (15.5, 14.9, 34.0)),
    m(BS, "Blend Swap CC-BY#microwave", TableTop, 360.0, (40.2, 35.8, 24.75)),
    m(BS, "Blend Swap CC-BY#radio", TableTop, 360.0, (30.7, 8.4, 26.3)),
    m(BS, "Blend Swap CC-BY#gift", TableTop, 90.0, (23.2, 18.1, 25.1)),
    m(BS, "Blend Swap CC-BY#tulips", TableTop, 0.0, (31.8, 25.2, 42.7)),
    m(BS, "Blend Swap CC-BY#white_lily", TableTop, 0.0, (37.1, 31.2, 60.0)),
    m(BS, "Blend Swap CC-BY#kitchenScale", TableTop, 0.0, (23.0, 23.0, 27.5)),
    m(BS, "Blend Swap CC-BY#breadBox", TableTop, 180.0, (56.2, 27.5, 27.5)),
];

/// The asset name a generated scene gives a curated model: the part of its id after `#`,
/// lower-cased, non-alphanumerics as `_`, prefixed by its catalog (`kl_`, `bs_`).
pub fn asset_name(m: &CuratedModel) -> String {
    let tail = m.id.rsplit('#').next().unwrap_or(m.id);
    let prefix = if m.catalog == KL { "kl" } else { "bs" };
    let body: String = tail
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c.to_ascii_lowercase() } else { '_' })
        .collect();
    format!("{prefix}_{body}")
}
