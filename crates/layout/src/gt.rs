//! `gt_layout.json`: the ground-truth layout that `assetfield synth` writes and `mine --gt`
//! reads. The schema is a contract: a top-level `instances` array whose entries carry `id`,
//! `category`, `position` `[x, y, z]` (footprint centre; z = base height), `yaw_deg`
//! (counter-clockwise about +Z), `scale`, `bev_aabb` `[xmin, ymin, xmax, ymax]`,
//! `yaw_symmetry_deg` and `supported_by` (id or null). Readers ignore unknown fields.
//!
//! [`GtLayout::to_json_with`] adds what the structs do not carry (they stay as they are, so
//! code that builds them field by field and old readers keep working): `units_per_metre`
//! at the top level and, on every instance whose asset is a catalog model, `source`
//! (catalog, model id, name, creator, licence).

use crate::error::LayoutError;
use crate::resolve::{ResolvedInstance, ResolvedLayout};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// Where an instance's model comes from (catalog models), written as its `source`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GtSource {
    /// The catalog's file name without `.sh3f`, e.g. `KatorLegaz`.
    pub catalog: String,
    /// The model's id in the catalog, e.g. `Kator Legaz#mid-century-chair`.
    pub id: String,
    /// The model's human name in the catalog.
    pub name: String,
    pub creator: String,
    /// The model's licence (its own, else the catalog's).
    pub license: String,
}

#[derive(Serialize)]
struct InstanceOut<'a> {
    #[serde(flatten)]
    instance: &'a GtInstance,
    #[serde(skip_serializing_if = "Option::is_none")]
    source: Option<&'a GtSource>,
}

#[derive(Serialize)]
struct LayoutOut<'a> {
    instances: Vec<InstanceOut<'a>>,
    containers: Vec<InstanceOut<'a>>,
    scene: &'a str,
    extent: [f32; 4],
    conventions: &'a str,
    #[serde(skip_serializing_if = "Option::is_none")]
    units_per_metre: Option<f32>,
}

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

    /// [`Self::to_json`] plus `units_per_metre` (when known) and a `source` on every instance
    /// whose asset is a key of `sources`.
    pub fn to_json_with(
        &self,
        units_per_metre: Option<f32>,
        sources: &BTreeMap<String, GtSource>,
    ) -> String {
        fn annotate<'a>(
            list: &'a [GtInstance],
            sources: &'a BTreeMap<String, GtSource>,
        ) -> Vec<InstanceOut<'a>> {
            list.iter()
                .map(|instance| InstanceOut { instance, source: sources.get(&instance.asset) })
                .collect()
        }
        let out = LayoutOut {
            instances: annotate(&self.instances, sources),
            containers: annotate(&self.containers, sources),
            scene: &self.scene,
            extent: self.extent,
            conventions: &self.conventions,
            units_per_metre,
        };
        serde_json::to_string_pretty(&out).expect("ground-truth layout serialises")
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

#[cfg(test)]
mod tests {
    use super::*;

    fn inst(asset: &str) -> GtInstance {
        GtInstance {
            id: 0,
            category: asset.into(),
            position: [1.0, 2.0, 0.0],
            yaw_deg: 30.0,
            scale: 1.0,
            bev_aabb: [0.0, 1.0, 2.0, 3.0],
            yaw_symmetry_deg: 360.0,
            supported_by: None,
            key: "a[0]".into(),
            asset: asset.into(),
            top: 0.8,
        }
    }

    #[test]
    fn annotated_json_keeps_every_field_and_adds_sources() {
        let gt = GtLayout {
            instances: vec![inst("chair"), inst("box")],
            containers: Vec::new(),
            scene: "s".into(),
            extent: [0.0, 0.0, 1.0, 1.0],
            conventions: "c".into(),
        };
        // without additions the text is exactly the plain one
        assert_eq!(gt.to_json_with(None, &BTreeMap::new()), gt.to_json());
        let src = GtSource {
            catalog: "KatorLegaz".into(),
            id: "Kator Legaz#x".into(),
            name: "X".into(),
            creator: "Kator Legaz".into(),
            license: "CC-BY".into(),
        };
        let text = gt.to_json_with(Some(1.5), &BTreeMap::from([("chair".to_string(), src)]));
        // old readers still read it
        let back: GtLayout = serde_json::from_str(&text).unwrap();
        assert_eq!(back, gt);
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(v["units_per_metre"], 1.5);
        assert_eq!(v["instances"][0]["source"]["creator"], "Kator Legaz");
        assert!(v["instances"][1].get("source").is_none());
    }
}
