//! Which grids of a smoke or fire cache belong in one asset, picked by the naming conventions of
//! the tools that write them: Blender/Mantaflow (`density`, `heat`, `flame`, `fuel`, …), Houdini
//! pyro (`density`, `temperature`, `flame` or `heat`) and EmberGen (`density`, `temperature`,
//! `flames`). `inspect` shows the pick and `cook --grids auto` cooks it.
//!
//! One grid per role, in role order: what absorbs (channel 0, the one plain renders show), what
//! is hot (the `--emission` channel), what burns. A name matches a role case-insensitively; the
//! role's names are tried in order, so Houdini's `temperature` wins over a `heat` beside it.
//! Only float grids count (doubles are read as f32), and only those on the first pick's
//! transform: the channels of an asset share one. Everything else (velocity, fuel, flags,
//! colour) is not cooked, as the scene does not render it.

use vdbcook_vdb::VdbFile;

/// The roles and the grid names that fill them, most specific first.
pub const ROLES: [(&str, &[&str]); 3] = [
    ("density", &["density", "smoke", "soot", "dens"]),
    ("temperature", &["temperature", "heat", "temp"]),
    // Houdini's `heat` is its pyro's burn field (0..1): it burns when a `temperature` took the
    // hot role (Blender's old smoke writes `heat` alone, as its temperature).
    ("flame", &["flame", "flames", "fire", "heat"]),
];

/// The pick for one file.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Pick {
    /// Grid names to cook, channel order.
    pub grids: Vec<String>,
    /// Grids that matched a role but were left out, each with why.
    pub skipped: Vec<(String, String)>,
}

/// The pick over `file`'s grids (empty when no grid matches a role).
pub fn suggest(file: &VdbFile) -> Pick {
    let mut pick = Pick::default();
    let mut first: Option<usize> = None;
    for (_, names) in ROLES {
        let candidates = names.iter().flat_map(|want| {
            file.grids
                .iter()
                .enumerate()
                .filter(move |(_, g)| g.name.eq_ignore_ascii_case(want))
        });
        for (i, g) in candidates {
            if !g.is_float() {
                pick.skipped.push((
                    g.name.clone(),
                    format!("a {} grid, not float", g.value_type),
                ));
                continue;
            }
            if let Some(f) = first {
                let t0 = &file.grids[f].transform;
                if !g.transform.approx_eq(t0, 1e-9) {
                    pick.skipped.push((
                        g.name.clone(),
                        format!(
                            "its transform (voxel size {:?}) differs from '{}' (voxel size {:?})",
                            g.transform.voxel_size(),
                            file.grids[f].name,
                            t0.voxel_size()
                        ),
                    ));
                    continue;
                }
            }
            if pick.grids.contains(&g.name) {
                continue;
            }
            first.get_or_insert(i);
            pick.grids.push(g.label.clone());
            break;
        }
    }
    pick
}
