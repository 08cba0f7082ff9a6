//! `gt_layout.json`: the ground-truth layout that `assetfield synth` writes and `mine --gt`
//! reads. The schema is a contract: a top-level `instances` array whose entries carry `id`,
//! `category`, `position` `[x, y, z]` (footprint centre; z = base height), `yaw_deg`
//! (counter-clockwise about +Z), `scale`, `bev_aabb` `[xmin, ymin, xmax, ymax]`,
//! `yaw_symmetry_deg` and `supported_by` (id or null). Readers ignore unknown fields.

use crate::error::LayoutError;
use crate::resolve::{ResolvedInstance, ResolvedLayout};
use serde::{Deserialize, Serialize};
use std::path::Path;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GtInstance {
    pub id: u32,
    pub category: String,
    pub position: [f32; 3],
    pub yaw_deg: f32,
    pub scale: f32,
    pub bev_aabb: [f32; 4],
    pub yaw_symmetry_deg: f32,
    pub supported_by: Option<u32>,
    /// Extra: the instance key in the script.
    #[serde(default)]
    pub key: String,
    /// Extra: the asset drawn (differs from the category after a replacement).
    #[serde(default)]
    pub asset: String,
    /// Extra: world height of the instance's top.
    #[serde(default)]
    pub top: f32,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GtLayout {
    pub instances: Vec<GtInstance>,
    /// Extra: background assets (floors, rooms); not objects to detect.
    #[serde(default)]
    pub containers: Vec<GtInstance>,
    #[serde(default)]
    pub scene: String,
    /// Extra: the ground region of interest `[xmin, ymin, xmax, ymax]`.
    #[serde(default)]
    pub extent: [f32; 4],
    /// Extra: conventions, for a human reader.
    #[serde(default)]
    pub conventions: String,
}

fn gt_instance(i: &ResolvedInstance) -> GtInstance {
    let t = &i.transform;
    GtInstance {
        id: i.id,
        category: i.category.clone(),
        position: [t.position.x, t.position.y, t.base],
        yaw_deg: t.yaw_deg,
        scale: t.scale,
        bev_aabb: i.bev_aabb.to_array(),
        yaw_symmetry_deg: i.yaw_symmetry_deg,
        supported_by: i.supported_by,
        key: i.key.clone(),
        asset: i.asset.clone(),
        top: i.top,
    }
}

impl GtLayout {
    pub fn from_resolved(layout: &ResolvedLayout) -> Self {
        GtLayout {
            instances: layout.objects().map(gt_instance).collect(),
            containers: layout.containers().map(gt_instance).collect(),
            scene: layout.name.clone(),
            extent: layout.extent.to_array(),
            conventions:
                "world Z up, ground = XY plane, scene units; yaw counter-clockwise about +Z \
                          in degrees; an asset's front faces its local +X"
                    .into(),
        }
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("ground-truth layout serialises")
    }

    pub fn read(path: &Path) -> Result<Self, LayoutError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| LayoutError::Io { path: path.to_path_buf(), source: e })?;
        serde_json::from_str(&text).map_err(|e| LayoutError::GtFormat {
            path: path.to_path_buf(),
            message: format!("line {} column {}: {e}", e.line(), e.column()),
        })
    }
}
