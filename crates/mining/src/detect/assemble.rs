//! Stage 6: the final list. Every part becomes a detection, and what the second round found
//! on it becomes detections supported by it, with their heights: base (the surface or the
//! ground they stand on), top and shape top.

use super::Detection;
use super::context::Ctx;
use super::shape::{Part, robust_top_level};
use super::unpack::Child;
use crate::error::{Result, check_interrupt};

/// The second round inside one part: what stands on it, and the top level of the surface
/// they stand on.
pub(super) type SecondRound = fn(&Ctx, &Part) -> (Vec<Child>, Option<usize>);

/// Detections of `parts` and of what the second round finds standing on them (ids equal
/// indices; children follow their parent).
pub(super) fn assemble(cx: &Ctx, parts: &[Part], second: SecondRound) -> Result<Vec<Detection>> {
    let (vol, grid, floor, ground, tau) = (cx.vol, cx.grid, cx.floor, cx.ground, cx.tau);
    let texel_area = grid.texel_area().max(1e-12);
    let mut detections: Vec<Detection> = Vec::new();
    for p in parts {
        check_interrupt()?;
        let (children, surface) =
            if cx.p.stages.unpack { second(cx, p) } else { (Vec::new(), None) };
        let id = detections.len();
        tracing::debug!(id, rect = ?p.rect, n = p.footprint.count(), kmin = p.kmin, kmax = p.kmax, children = children.len(), "detection");
        let mut own = p.footprint.clone();
        let mut child_dets = Vec::new();
        for ch in &children {
            // clear the child (and a one-texel halo) from the parent's own texels
            for r in ch.rect.r0.saturating_sub(1)..ch.rect.r1 + 1 {
                for c in ch.rect.c0.saturating_sub(1)..ch.rect.c1 + 1 {
                    let near = (r.saturating_sub(1)..=r + 1).any(|rr| {
                        (c.saturating_sub(1)..=c + 1).any(|cc| {
                            ch.rect.contains(rr, cc)
                                && ch.footprint.get(rr - ch.rect.r0, cc - ch.rect.c0)
                        })
                    });
                    if near && p.rect.contains(r, c) {
                        own.set(r - p.rect.r0, c - p.rect.c0, false);
                    }
                }
            }
            let base = vol.height(surface.unwrap_or(p.kmax));
            child_dets.push(Detection {
                id: 0,
                rect: ch.rect,
                footprint: ch.footprint.clone(),
                own: ch.footprint.clone(),
                world: grid.rect_to_world(ch.rect),
                area: ch.footprint.count() as f32 * texel_area,
                base,
                top: vol.height(ch.kmax),
                shape_top: vol.height(robust_top_level(
                    vol,
                    ch.rect,
                    &ch.footprint,
                    surface.unwrap_or(p.kmax),
                    ch.kmax,
                    tau,
                )),
                parent: Some(id),
                children: Vec::new(),
            });
        }
        if own.count() == 0 {
            own = p.footprint.clone();
        }
        let (top, shape_top) = match (surface, children.is_empty()) {
            (Some(s), false) => (vol.height(s), vol.height(s)),
            _ => (
                vol.height(p.kmax),
                vol.height(robust_top_level(vol, p.rect, &p.footprint, p.kmin, p.kmax, tau)),
            ),
        };
        // on no support, an object stands on the ground, whatever its lowest opaque level (a
        // pedestal, legs or a stem too thin for the field leave it floating over it; the
        // layout places it on the ground): the level above the floor's top, with no floor
        // found the level below the ground
        let base = floor.map_or(vol.height_below(ground), |f| vol.height(f.hi + 1));
        detections.push(Detection {
            id,
            rect: p.rect,
            footprint: p.footprint.clone(),
            own,
            world: grid.rect_to_world(p.rect),
            area: p.footprint.count() as f32 * texel_area,
            base,
            top,
            shape_top,
            parent: None,
            children: Vec::new(),
        });
        for mut c in child_dets {
            c.id = detections.len();
            detections[id].children.push(c.id);
            detections.push(c);
        }
    }
    Ok(detections)
}
