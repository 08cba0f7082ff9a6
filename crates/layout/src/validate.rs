//! The numbers of a script, checked once when it is loaded: every position, angle, size,
//! scale, colour and setting must be finite, and positive (or in its range) where it must.
//! RON reads `NaN` and `inf` as numbers; without this pass they would flow through
//! resolution into the ground truth (`null` matrices in `transforms_*.json`).
//!
//! Every command that loads a script ([`crate::load`], [`crate::load_str`],
//! [`crate::append_edits`]) runs this pass, so `layout`, `synth`, `compose` and `mine` refuse
//! the same scripts with the same [`LayoutError::Invalid`] message, located at the item,
//! edit, asset or setting that holds the value.

use crate::error::{InvalidValue, LayoutError, Location};
use crate::script::{
    AssetDef, CaptureSettings, Edit, Facing, Item, LibraryRef, Lighting, ObjSource, Part, Region,
    Script, V2, V3, Variation, ViewSettings,
};
use crate::source::{EditNode, ItemNode, SourceFile};
use std::fmt::Display;

/// Characters no instance name may hold: the wildcards that make a key a pattern.
pub(crate) const NAME_RESERVED: [char; 2] = ['*', '?'];

/// The place and name of what holds the values being checked.
struct Check<'a> {
    location: &'a Location,
    item: String,
}

impl Check<'_> {
    fn fail(&self, field: &str, value: impl Display, expected: &str) -> LayoutError {
        LayoutError::Invalid(Box::new(InvalidValue {
            location: self.location.clone(),
            item: self.item.clone(),
            field: field.to_string(),
            value: value.to_string(),
            expected: expected.to_string(),
        }))
    }

    fn finite(&self, field: &str, v: f32) -> Result<(), LayoutError> {
        if v.is_finite() { Ok(()) } else { Err(self.fail(field, v, "a finite number")) }
    }

    fn positive(&self, field: &str, v: f32) -> Result<(), LayoutError> {
        if v.is_finite() && v > 0.0 { Ok(()) } else { Err(self.fail(field, v, "positive")) }
    }

    fn non_negative(&self, field: &str, v: f32) -> Result<(), LayoutError> {
        if v.is_finite() && v >= 0.0 { Ok(()) } else { Err(self.fail(field, v, "at least 0")) }
    }

    fn within(&self, field: &str, v: f32, lo: f32, hi: f32) -> Result<(), LayoutError> {
        if v.is_finite() && (lo..=hi).contains(&v) {
            Ok(())
        } else {
            Err(self.fail(field, v, &format!("between {lo} and {hi}")))
        }
    }

    /// An instance name: it becomes part of keys, and a key names its instance in an edit
    /// as it is, so a name holds no wildcard (`*`, `?`), does not start with `#` (an id),
    /// has no spaces at its ends and is not empty.
    fn name(&self, field: &str, name: Option<&str>) -> Result<(), LayoutError> {
        match name {
            Some(n)
                if n.is_empty()
                    || n.contains(NAME_RESERVED)
                    || n.starts_with('#')
                    || n.trim() != n =>
            {
                Err(self.fail(
                    field,
                    format!("{n:?}"),
                    "a non-empty name without * or ?, not starting with # and without spaces at its ends (keys are built from names, and an edit's key names its instance as written)",
                ))
            }
            _ => Ok(()),
        }
    }

    fn point(&self, field: &str, p: V2) -> Result<(), LayoutError> {
        if p.0.is_finite() && p.1.is_finite() {
            Ok(())
        } else {
            Err(self.fail(field, format!("({}, {})", p.0, p.1), "a point of finite numbers"))
        }
    }

    fn point3(&self, field: &str, p: V3) -> Result<(), LayoutError> {
        if p.0.is_finite() && p.1.is_finite() && p.2.is_finite() {
            Ok(())
        } else {
            let v = format!("({}, {}, {})", p.0, p.1, p.2);
            Err(self.fail(field, v, "a point of finite numbers"))
        }
    }

    fn size3(&self, field: &str, s: V3) -> Result<(), LayoutError> {
        if [s.0, s.1, s.2].iter().all(|v| v.is_finite() && *v > 0.0) {
            Ok(())
        } else {
            let v = format!("({}, {}, {})", s.0, s.1, s.2);
            Err(self.fail(field, v, "three positive sizes"))
        }
    }

    fn color(&self, field: &str, c: V3) -> Result<(), LayoutError> {
        if [c.0, c.1, c.2].iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v)) {
            Ok(())
        } else {
            let v = format!("({}, {}, {})", c.0, c.1, c.2);
            Err(self.fail(field, v, "a colour of three numbers between 0 and 1"))
        }
    }

    fn points(&self, field: &str, pts: &[V2]) -> Result<(), LayoutError> {
        for (k, p) in pts.iter().enumerate() {
            self.point(&format!("{field}[{k}]"), *p)?;
        }
        Ok(())
    }

    fn facing(&self, face: &Facing) -> Result<(), LayoutError> {
        match face {
            Facing::Toward(x, y) => self.point("face: Toward", (*x, *y)),
            _ => Ok(()),
        }
    }

    fn vary(&self, vary: &Option<Variation>) -> Result<(), LayoutError> {
        let Some(v) = vary else { return Ok(()) };
        self.non_negative("vary.yaw_jitter_deg", v.yaw_jitter_deg)?;
        for (k, y) in v.yaw_choices.iter().enumerate() {
            self.finite(&format!("vary.yaw_choices[{k}]"), *y)?;
        }
        // the scale is multiplied by a factor in [1 - s, 1 + s], which must stay positive
        if !(v.scale_jitter.is_finite() && (0.0..1.0).contains(&v.scale_jitter)) {
            return Err(self.fail("vary.scale_jitter", v.scale_jitter, "at least 0 and below 1"));
        }
        self.non_negative("vary.position_jitter", v.position_jitter)
    }

    fn region(&self, region: &Region) -> Result<(), LayoutError> {
        match region {
            Region::Rect { min, max } => {
                self.point("region: Rect min", *min)?;
                self.point("region: Rect max", *max)
            }
            Region::Circle { center, radius } => {
                self.point("region: Circle center", *center)?;
                self.non_negative("region: Circle radius", *radius)
            }
            Region::Polygon(pts) => self.points("region: Polygon", pts),
        }
    }
}

/// Check the placement items of a file (with their children).
pub(crate) fn items(nodes: &[ItemNode]) -> Result<(), LayoutError> {
    for n in nodes {
        item(&n.item, &n.location)?;
        items(&n.children)?;
    }
    Ok(())
}

/// Check one item's own values (not its children's).
fn item(item: &Item, location: &Location) -> Result<(), LayoutError> {
    let c = Check { location, item: item.variant().to_string() };
    c.name("name", item.name())?;
    match item {
        Item::Instance { at, yaw, scale, base, .. } => {
            c.point("at", *at)?;
            c.finite("yaw", *yaw)?;
            c.positive("scale", *scale)?;
            c.finite("base", *base)
        }
        Item::Row { from, to, yaw, face, scale, vary, .. } => {
            c.point("from", *from)?;
            c.point("to", *to)?;
            c.finite("yaw", *yaw)?;
            c.facing(face)?;
            c.positive("scale", *scale)?;
            c.vary(vary)
        }
        Item::Grid { center, spacing, yaw, scale, vary, .. } => {
            c.point("center", *center)?;
            c.point("spacing", *spacing)?;
            c.finite("yaw", *yaw)?;
            c.positive("scale", *scale)?;
            c.vary(vary)
        }
        Item::Ring { center, radius, start_deg, face, yaw, scale, vary, .. } => {
            c.point("center", *center)?;
            c.non_negative("radius", *radius)?;
            c.finite("start_deg", *start_deg)?;
            c.facing(face)?;
            c.finite("yaw", *yaw)?;
            c.positive("scale", *scale)?;
            c.vary(vary)
        }
        Item::Scatter { region, min_distance, yaw, scale, vary, .. } => {
            c.region(region)?;
            c.non_negative("min_distance", *min_distance)?;
            c.finite("yaw", *yaw)?;
            c.positive("scale", *scale)?;
            c.vary(vary)
        }
        Item::Along { path, spacing, offset, face, yaw, scale, vary, .. } => {
            c.points("path", path)?;
            if let Some(s) = spacing {
                c.positive("spacing", *s)?;
            }
            c.finite("offset", *offset)?;
            c.facing(face)?;
            c.finite("yaw", *yaw)?;
            c.positive("scale", *scale)?;
            c.vary(vary)
        }
        Item::Group { at, yaw, scale, base, .. } => {
            c.point("at", *at)?;
            c.finite("yaw", *yaw)?;
            c.positive("scale", *scale)?;
            c.finite("base", *base)
        }
    }
}

/// Check the edits of a file.
pub(crate) fn edits(nodes: &[EditNode]) -> Result<(), LayoutError> {
    nodes.iter().try_for_each(|n| edit(&n.edit, &n.location))
}

fn edit(edit: &Edit, location: &Location) -> Result<(), LayoutError> {
    let c = Check { location, item: edit.variant().to_string() };
    let point = |field: &str, p: &Option<V2>| p.map_or(Ok(()), |p| c.point(field, p));
    let finite = |field: &str, v: &Option<f32>| v.map_or(Ok(()), |v| c.finite(field, v));
    let positive = |field: &str, v: &Option<f32>| v.map_or(Ok(()), |v| c.positive(field, v));
    match edit {
        Edit::Remove(_) | Edit::RemoveCategory(_) | Edit::ReplaceAsset { .. } => Ok(()),
        Edit::NameCategory { name, .. } if name.trim().is_empty() => {
            Err(c.fail("name", format!("{name:?}"), "a name with a visible character"))
        }
        Edit::NameCategory { .. } => Ok(()),
        Edit::Move { to, by, .. } => {
            point("to", to)?;
            point("by", by)
        }
        Edit::Rotate { to, by, .. } => {
            finite("to", to)?;
            finite("by", by)
        }
        // named as before this pass existed ("scale must be positive")
        Edit::Scale { to, by, .. } => {
            positive("scale", to)?;
            positive("scale factor", by)
        }
        Edit::Duplicate { at, by, yaw, name, .. } => {
            c.name("name", name.as_deref())?;
            point("at", at)?;
            point("by", by)?;
            finite("yaw", yaw)
        }
        Edit::Add { at, yaw, scale, name, .. } => {
            c.name("name", name.as_deref())?;
            c.point("at", *at)?;
            finite("yaw", yaw)?;
            positive("scale", scale)
        }
        Edit::Override { at, yaw, scale, base, .. } => {
            point("at", at)?;
            finite("yaw", yaw)?;
            positive("scale", scale)?;
            finite("base", base)
        }
    }
}

/// Check an asset definition (its parts, mesh and library patch).
pub(crate) fn asset(name: &str, def: &AssetDef, location: &Location) -> Result<(), LayoutError> {
    let c = Check { location, item: format!("asset \"{name}\"") };
    c.within("yaw_symmetry_deg", def.yaw_symmetry_deg, 0.0, 360.0)?;
    for (k, p) in def.parts.iter().enumerate() {
        part(p, &Check { location, item: format!("asset \"{name}\", part {}", k + 1) })?;
    }
    if let Some(ObjSource::Obj { scale, yaw_deg, .. }) = &def.obj {
        c.positive("obj.scale", *scale)?;
        c.finite("obj.yaw_deg", *yaw_deg)?;
    }
    if let Some(l) = &def.library {
        library(l, &c)?;
    }
    Ok(())
}

fn part(p: &Part, c: &Check<'_>) -> Result<(), LayoutError> {
    match p {
        Part::Box { center, size, color, yaw } => {
            c.point3("Box center", *center)?;
            c.size3("Box size", *size)?;
            c.color("Box color", *color)?;
            c.finite("Box yaw", *yaw)
        }
        Part::Cylinder { base, radius, height, color, .. } => {
            c.point3("Cylinder base", *base)?;
            c.positive("Cylinder radius", *radius)?;
            c.positive("Cylinder height", *height)?;
            c.color("Cylinder color", *color)
        }
        Part::Cone { base, radius, top_radius, height, color } => {
            c.point3("Cone base", *base)?;
            c.non_negative("Cone radius", *radius)?;
            c.non_negative("Cone top_radius", *top_radius)?;
            if *radius == 0.0 && *top_radius == 0.0 {
                return Err(c.fail("Cone radius", radius, "above 0 where top_radius is 0"));
            }
            c.positive("Cone height", *height)?;
            c.color("Cone color", *color)
        }
        Part::Sphere { center, radius, color } => {
            c.point3("Sphere center", *center)?;
            c.positive("Sphere radius", *radius)?;
            c.color("Sphere color", *color)
        }
    }
}

fn library(l: &LibraryRef, c: &Check<'_>) -> Result<(), LayoutError> {
    c.size3("library.size", l.size)?;
    if let Some(p) = l.pivot {
        c.point("library.pivot", p)?;
    }
    Ok(())
}

/// Check the scene-wide settings of a file: `extent`, `units_per_metre`, `views` and
/// `lighting`, each located at its field name.
pub(crate) fn settings(script: &Script, src: &SourceFile) -> Result<(), LayoutError> {
    if let Some((a, b)) = script.extent {
        let location = src.find_ident("extent", 0);
        let c = Check { location: &location, item: "extent".into() };
        c.point("extent min", a)?;
        c.point("extent max", b)?;
        let far = crate::resolve::MAX_COORDINATE;
        for (field, p) in [("extent min", a), ("extent max", b)] {
            if p.0.abs() > far || p.1.abs() > far {
                let v = format!("({}, {})", p.0, p.1);
                return Err(c.fail(field, v, &format!("a point within {far} scene units")));
            }
        }
    }
    if let Some(u) = script.units_per_metre {
        let location = src.find_ident("units_per_metre", 0);
        Check { location: &location, item: "scene".into() }.positive("units_per_metre", u)?;
    }
    if let Some(v) = &script.views {
        views(v, &src.find_ident("views", 0))?;
    }
    if let Some(l) = &script.lighting {
        lighting(l, &src.find_ident("lighting", 0))?;
    }
    Ok(())
}

/// Check a scene's camera rig settings against the ranges [`ViewSettings`] documents.
pub fn views(v: &ViewSettings, location: &Location) -> Result<(), LayoutError> {
    let c = Check { location, item: "views".into() };
    if let Some(n) = v.count
        && !ViewSettings::COUNT.contains(&n)
    {
        let r = ViewSettings::COUNT;
        return Err(c.fail("count", n, &format!("between {} and {}", r.start(), r.end())));
    }
    if let Some(t) = v.test {
        let max = v.count.map_or(*ViewSettings::COUNT.end(), |n| n.saturating_sub(1)).max(1);
        if !(1..=max).contains(&t) {
            let within = if v.count.is_some() { " (count - 1)" } else { "" };
            return Err(c.fail("test", t, &format!("between 1 and {max}{within}")));
        }
    }
    if let Some(r) = v.resolution
        && !ViewSettings::RESOLUTION_PX.contains(&r)
    {
        let p = ViewSettings::RESOLUTION_PX;
        return Err(c.fail("resolution", r, &format!("{}..={} pixels", p.start(), p.end())));
    }
    if let Some(r) = v.radius {
        c.positive("radius", r)?;
    }
    if let Some((lo, hi)) = v.elevation_deg {
        let (a, b) = (*ViewSettings::ELEVATION_DEG.start(), *ViewSettings::ELEVATION_DEG.end());
        if !(lo.is_finite() && hi.is_finite() && a <= lo && lo <= hi && hi <= b) {
            let expected = format!("(min, max) degrees with {a} <= min <= max <= {b}");
            return Err(c.fail("elevation_deg", format!("({lo}, {hi})"), &expected));
        }
    }
    if let Some(f) = v.fov_deg {
        let r = ViewSettings::FOV_DEG;
        c.within("fov_deg", f, *r.start(), *r.end())?;
    }
    if let Some(cap) = &v.capture {
        let c = Check { location, item: "views.capture".into() };
        if let Some(h) = cap.eye_height {
            c.positive("eye_height", h)?;
        }
        if let Some(d) = cap.path_inset {
            c.positive("path_inset", d)?;
        }
        let stops = CaptureSettings::EXPOSURE_STOPS;
        if let Some(e) = cap.exposure_stops {
            c.within("exposure_stops", e, *stops.start(), *stops.end())?;
        }
        let spread = CaptureSettings::SPREAD;
        if let Some(w) = cap.white_balance {
            c.within("white_balance", w, *spread.start(), *spread.end())?;
        }
        if let Some(n) = cap.noise {
            c.within("noise", n, *spread.start(), *spread.end())?;
        }
    }
    Ok(())
}

fn lighting(l: &Lighting, location: &Location) -> Result<(), LayoutError> {
    let c = Check { location, item: "lighting".into() };
    if let Some(d) = l.direction {
        c.point3("direction", d)?;
        if d == (0.0, 0.0, 0.0) {
            return Err(c.fail("direction", "(0, 0, 0)", "a direction (not all zero)"));
        }
    }
    if let Some(a) = l.ambient {
        c.within("ambient", a, 0.0, 1.0)?;
    }
    Ok(())
}
