//! Pivots: the point of an object that a layout places and turns about. People turn a street
//! lamp about its pole and a car about the middle of its wheels, not about the centre of
//! their bounding boxes (a lamp's arm reaches a metre to one side). The pivot of a mined
//! object is the centre of the bounding box of its **ground contact**: the texels of its own
//! footprint occupied in most of the lowest levels above the surface it stands on
//! (a leg or a pole runs through them; paint on the floor or the floor's blur touches only
//! the first). For most furniture
//! (legs at the corners, a solid base) that is the box centre. The field's lowest levels are
//! its least certain (a thin foot merges with the floor slab, a neighbour's panel reaches
//! into a footprint), so the pivot leaves the box centre only on clear evidence: the contact
//! lies beside the box centre, is a compact post (at most [`MAX_CONTACT_SHARE`] of the
//! object, its box at most [`MAX_CONTACT_ASPECT`] times longer than wide), and a column
//! rises from it through at least [`MIN_COLUMN_SHARE`] of the object's height (a pole
//! carrying an arm); a pivot within the pose search's sub-texel offset bound of the centre
//! ([`crate::yaw::YawOptions::max_offset`], half the field's blur: what a pose cannot tell
//! apart) is the centre.
//!
//! Every decision is logged with `tracing` at debug level; at trace level also the contact
//! map of objects whose pivot stays centred (`#` contact, `+` touched in too few levels, `o`
//! free, `.` not the object's): `ASSETFIELD_LOG=assetfield_mining::pivot=trace`.

use glam::Vec2;

use crate::detect::{Detection, Detections};
use crate::planes::OpacityVolume;

/// Share of an object's height counted as its contact band (at least the field's vertical
/// blur, [`Detections::blur_levels`], so that the band reaches past the blur of the surface
/// it stands on: 2 levels mined positions worse on two dev fields, `random_6` at 2000
/// iterations and the suite's living room): a chair's legs, a lamp's foot, a car's wheels.
pub const CONTACT_BAND: f32 = 0.1; // tuned: pivot.contact_band

/// Largest share of an object's own texels its contact may cover for the pivot to leave the
/// box centre.
pub const MAX_CONTACT_SHARE: f32 = 0.25; // tuned: pivot.max_contact_share

/// Largest aspect ratio of the contact's box for the pivot to leave the box centre: a post
/// (a pole, a trunk), not a panel or a strip of a neighbour's foot.
pub const MAX_CONTACT_ASPECT: f32 = 2.0; // tuned: pivot.max_contact_aspect

/// Smallest share of the levels from the contact to the object's top at which the contact's
/// box must be occupied (a column carrying the object, not a neighbour's foot in its mask).
pub const MIN_COLUMN_SHARE: f32 = 0.8; // tuned: pivot.min_column_share

/// World centre of a detection's box.
pub fn box_centre(d: &Detection) -> Vec2 {
    (d.world.min + d.world.max) * 0.5
}

/// The pivot of every detection (world XY), in detection order; `snap_texels` is the pose
/// search's offset bound ([`crate::yaw::YawOptions::max_offset`]).
pub fn contact_pivots(vol: &OpacityVolume, dets: &Detections, snap_texels: f32) -> Vec<Vec2> {
    dets.detections.iter().map(|d| contact_pivot(vol, dets, d, snap_texels)).collect()
}

/// The pivot of one detection (see the module docs); its box centre when nothing of it
/// touches the ground in the volume, or when the pivot lies within `snap_texels` of it.
pub fn contact_pivot(vol: &OpacityVolume, dets: &Detections, d: &Detection, snap: f32) -> Vec2 {
    let centre = box_centre(d);
    if vol.nz == 0 || vol.dz <= 0.0 || vol.rows != dets.grid.rows || vol.cols != dets.grid.cols {
        return centre;
    }
    // first level above the supporting surface
    let (k_base, _) = vol.levels_between(d.base, d.top);
    let k0 = if d.parent.is_some() { k_base } else { k_base.max(dets.start_level) };
    let band =
        (((d.top - d.base).max(0.0) * CONTACT_BAND / vol.dz).ceil() as usize).max(dets.blur_levels);
    let k1 = (k0 + band).min(vol.nz);
    if k0 >= k1 {
        return centre;
    }
    let tau = dets.voxel_threshold;
    // levels of the band a column holds, and whether that makes it a contact
    let held_at =
        |rr: usize, cc: usize| vol.column(rr, cc)[k0..k1].iter().filter(|&&o| o > tau).count();
    let is_contact = |held: usize| 2 * held > k1 - k0;
    let (mut rmin, mut rmax, mut cmin, mut cmax) = (usize::MAX, 0, usize::MAX, 0);
    let (mut contact, mut own) = (0usize, 0usize);
    for r in 0..d.rect.rows() {
        for c in 0..d.rect.cols() {
            if !d.own.get(r, c) {
                continue;
            }
            own += 1;
            let (rr, cc) = (d.rect.r0 + r, d.rect.c0 + c);
            if is_contact(held_at(rr, cc)) {
                contact += 1;
                rmin = rmin.min(rr);
                rmax = rmax.max(rr);
                cmin = cmin.min(cc);
                cmax = cmax.max(cc);
            }
        }
    }
    if contact == 0 {
        tracing::debug!(id = d.id, rect = ?d.rect, k0, k1, tau, "pivot: no contact");
        return centre;
    }
    let pivot = dets.grid.to_world((cmin + cmax) as f32 * 0.5, (rmin + rmax) as f32 * 0.5);
    let texel = Vec2::new(dets.grid.texel[0], dets.grid.texel[1]);
    if ((pivot - centre) / texel).length() <= snap {
        if tracing::enabled!(tracing::Level::TRACE) {
            let mut map = String::new();
            for r in 0..d.rect.rows() {
                map.extend((0..d.rect.cols()).map(|c| {
                    let held = held_at(d.rect.r0 + r, d.rect.c0 + c);
                    if !d.own.get(r, c) {
                        '.'
                    } else if is_contact(held) {
                        '#'
                    } else if held > 0 {
                        '+'
                    } else {
                        'o'
                    }
                }));
                map.push('\n');
            }
            tracing::trace!(id = d.id, k0, k1, base = d.base, top = d.top, "contact map:\n{map}");
        }
        tracing::debug!(id = d.id, contact, own, "pivot: contact centred");
        return centre;
    }
    // the box centre must lie off the contact, the contact be small, and a column rise from
    // it through the object (a pole carrying an arm)
    let (cc, cr) = dets.grid.to_texel(centre);
    let off = cc < cmin as f32 - 1.0
        || cc > cmax as f32 + 1.0
        || cr < rmin as f32 - 1.0
        || cr > rmax as f32 + 1.0;
    let (h, w) = ((rmax + 1 - rmin) as f32, (cmax + 1 - cmin) as f32);
    let small = contact as f32 <= MAX_CONTACT_SHARE * own as f32
        && h.max(w) <= MAX_CONTACT_ASPECT * h.min(w);
    let k_top = (((d.top - vol.z0) / vol.dz).round().max(0.0) as usize).min(vol.nz - 1);
    let carried = if k_top >= k0 {
        let held = (k0..=k_top)
            .filter(|&k| {
                (rmin..=rmax).any(|r| {
                    (cmin..=cmax).any(|c| {
                        let (lr, lc) = (r - d.rect.r0, c - d.rect.c0);
                        d.own.get(lr, lc) && vol.column(r, c)[k] > tau
                    })
                })
            })
            .count();
        held as f32 >= MIN_COLUMN_SHARE * (k_top + 1 - k0) as f32
    } else {
        false
    };
    tracing::debug!(
        id = d.id,
        rect = ?d.rect,
        k0,
        k1,
        rmin,
        rmax,
        cmin,
        cmax,
        contact,
        own,
        %pivot,
        %centre,
        off,
        small,
        carried,
        "pivot"
    );
    if off && small && carried { pivot } else { centre }
}
