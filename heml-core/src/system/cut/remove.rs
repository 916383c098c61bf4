//! [`System::remove_tets`] and [`System::cut`]: the tet set shrinks between steps,
//! and everything built on it follows, locally.

use super::blade::{bounds, span, triangle_meets_tet, Blade};
use super::topology::Topology;
use crate::error::{HemlError, Result};
use crate::system::{Prescribed, Ramp, System};
use crate::Vec3;
use rayon::prelude::*;

/// What a cut did.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CutReport {
    /// The tets removed (global ids, ascending).
    pub removed_tets: Vec<usize>,
    /// The mass they carried, Σ ρ Vol (kg): the system's total mass fell by this.
    pub removed_mass: f64,
    /// Nodes left with no tet, ascending: dropped from the dynamics (zero mass, held
    /// where they are, no reaction).
    pub orphaned_nodes: Vec<usize>,
    /// Tets left in the system.
    pub remaining_tets: usize,
}

impl System {
    /// Builds what cuts need (tet neighbours, regions per tet, the surface's face
    /// index): O(n log n) once. The first cut calls it; a simulator that must not
    /// stall on its first cut calls it up front.
    pub fn prepare_cutting(&mut self) {
        if self.model.cut.topo.is_some() {
            return;
        }
        let mut region_of = vec![0u32; self.model.mesh.n_tets()];
        for (r, region) in self.model.regions.iter().enumerate() {
            for &t in region.field.tet_ids() {
                region_of[t] = r as u32;
            }
        }
        let mut topo = Topology::new(
            self.model.mesh.tets(),
            self.model.mesh.n_nodes(),
            region_of,
            &self.model.surface,
        );
        // overlapping covers: the surface stays cover 0's (`BoundarySurface::of_tet_mesh`)
        if self.model.mesh.overlap().is_some() {
            let mesh = &self.model.mesh;
            topo.off_surface = (0..mesh.n_tets()).map(|t| mesh.tet_cover(t) != 0).collect();
        }
        for r in &mut self.model.regions {
            // builds the field's id index (a field that cannot remove tets says so
            // when a cut reaches it)
            let _ = r.field.remove_tets(&[]);
        }
        self.model.cut.topo = Some(Box::new(topo));
    }

    /// Whether tet `t` is still in the system (not removed by a cut).
    pub fn tet_alive(&self, t: usize) -> bool {
        match &self.model.cut.topo {
            Some(topo) => topo.alive.get(t).copied().unwrap_or(false),
            None => t < self.model.mesh.n_tets(),
        }
    }

    /// Number of tets still in the system.
    pub fn n_tets_alive(&self) -> usize {
        self.model
            .cut
            .topo
            .as_ref()
            .map_or(self.model.mesh.n_tets(), |t| t.n_alive)
    }

    /// The ids of the tets still in the system, ascending (all of the mesh's until a
    /// cut).
    pub fn alive_tets(&self) -> Vec<usize> {
        (0..self.model.mesh.n_tets()).filter(|&t| self.tet_alive(t)).collect()
    }

    /// How many cuts changed the tet set: caches built on it (an
    /// [`AdaptiveStep`](crate::system::AdaptiveStep)'s geometry, a viewer's mesh)
    /// compare it to know when to refresh.
    pub fn topology_version(&self) -> u64 {
        self.model.cut.version
    }

    /// The connected components of the remaining tets (tets sharing a face are
    /// connected): the component of each tet of the mesh (`usize::MAX` for removed
    /// ones) and their number. O(n) (it builds the cut topology first if no cut
    /// has, hence `&mut self`).
    pub fn tet_components(&mut self) -> (Vec<usize>, usize) {
        self.prepare_cutting();
        self.model.cut.topo.as_ref().map_or((Vec::new(), 0), |t| t.components())
    }

    /// Removes the tets crossed by `blade` at the current positions (see
    /// [`System::remove_tets`]). The search tests each tet's bounding box at the
    /// current positions against the blade's, in parallel (O(n) comparisons, less
    /// than a force evaluation: the positions change every step, so no spatial index
    /// would stay valid), then the exact triangle–tet test on the few left. A blade
    /// meeting no tet is an error.
    pub fn cut(&mut self, blade: &Blade) -> Result<CutReport> {
        self.check_between_steps("cut")?;
        blade.check()?;
        let tris = blade.triangles();
        let (lo, hi) = bounds(tris.iter().flatten());
        self.prepare_cutting();
        let alive: &[bool] = self.model.cut.topo.as_ref().map_or(&[], |t| &t.alive);
        let (x, tets) = (&self.state.x, self.model.mesh.tets());
        let hit: Vec<usize> = (0..tets.len())
            .into_par_iter()
            .with_min_len(4096)
            .filter(|&t| {
                if !alive.get(t).copied().unwrap_or(false) {
                    return false;
                }
                let p = crate::mesh::corners(x, &tets[t]);
                for d in 0..3 {
                    let (a, b) = p.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), q| {
                        (a.min(q[d]), b.max(q[d]))
                    });
                    if a > hi[d] || b < lo[d] {
                        return false;
                    }
                }
                tris.iter().any(|tri| triangle_meets_tet(tri, &p))
            })
            .collect();
        if hit.is_empty() {
            // where the body is now, so that a blade placed from the rest shape (a
            // body that has since sagged or been pushed away) can be moved onto it
            let live_points = || {
                (0..tets.len())
                    .filter(|&t| alive.get(t).copied().unwrap_or(false))
                    .flat_map(|t| tets[t].map(|i| &x[i as usize]))
            };
            let body = bounds(live_points());
            // and the body's point nearest the blade's box: how far to move it (the
            // body's box alone can overlap the blade's while the body misses it,
            // e.g. a sagged strip's tip below a blade placed at rest)
            let outside = |q: &Vec3| {
                (0..3)
                    .map(|d| (lo[d] - q[d]).max(q[d] - hi[d]).max(0.0).powi(2))
                    .sum::<f64>()
            };
            let nearest = live_points().min_by(|a, b| outside(a).total_cmp(&outside(b)));
            let near = nearest.map_or(String::new(), |q| {
                format!(
                    "; its nearest point, ({}) m, is {:.3e} m from the blade's box",
                    q.iter().map(|v| format!("{v:.4}")).collect::<Vec<_>>().join(", "),
                    outside(q).sqrt()
                )
            });
            return Err(HemlError::Invalid(format!(
                "the blade meets no tet of the body: nothing to cut (the blade spans {}; the body now spans {}{near})",
                span(lo, hi),
                span(body.0, body.1)
            )));
        }
        self.remove_tets(&hit)
    }

    /// Removes tets (global ids) between steps, as a cut does: their lanes in the
    /// force fields are masked, their lumped mass ρVol/4 leaves each corner, their
    /// faces leave the [boundary surface](System::surface) and the faces they shared
    /// with remaining tets join it, surface loads drop their faces, the Prony
    /// history at their nodes loses their share (estimated as α_i × their current
    /// forces, exact once the forces have been steady for a few τ_i: the history is
    /// kept per node), and nodes left with no tet
    /// are dropped from the dynamics: zero mass, held where they are (no 1/m, no
    /// drift, no reaction, no nodal force). The cached forces are invalidated; an
    /// implicit solver rebuilds its tangents at its next step (it notices the new
    /// tet set), an [`AdaptiveStep`](crate::system::AdaptiveStep) should be renewed
    /// (see [`System::topology_version`]). The stable step estimate is kept: removing
    /// tets cannot lower it (each remaining tet keeps its mass share and stiffness,
    /// and the largest frequency is bounded by the tets' own).
    ///
    /// Cost: O(removed tets × their neighbours) after the first cut, which also
    /// builds the topology ([`System::prepare_cutting`], O(n log n)).
    ///
    /// Errors, with the system unchanged: inside a step, an empty list, an id out of
    /// range or already removed, or a list that would remove every remaining tet.
    /// Duplicates are removed once.
    pub fn remove_tets(&mut self, tets: &[usize]) -> Result<CutReport> {
        self.check_between_steps("remove_tets")?;
        if tets.is_empty() {
            return Err(HemlError::Invalid("remove_tets: the list of tets is empty".into()));
        }
        let n = self.model.mesh.n_tets();
        if let Some(&bad) = tets.iter().find(|&&t| t >= n) {
            return Err(HemlError::Invalid(format!(
                "remove_tets: tet id {bad} is out of range (the mesh has {n} tets, ids 0..{})",
                n.saturating_sub(1)
            )));
        }
        if let Some(&gone) = tets.iter().find(|&&t| !self.tet_alive(t)) {
            return Err(HemlError::Invalid(format!(
                "remove_tets: tet {gone} was removed by an earlier cut"
            )));
        }
        let mut removed = tets.to_vec();
        removed.sort_unstable();
        removed.dedup();
        if removed.len() >= self.n_tets_alive() {
            return Err(HemlError::Invalid(format!(
                "remove_tets: removing {} tet(s) would leave no tet (the body has {} left)",
                removed.len(),
                self.n_tets_alive()
            )));
        }
        self.prepare_cutting();
        let Some(mut topo) = self.model.cut.topo.take() else {
            return Err(HemlError::Invalid("remove_tets: no cut topology".into()));
        };
        // the force fields first: the only step that can fail (it does not, as the
        // regions' tets are those the topology was built from), before any change;
        // the viscous regions' removed tets' forces first of all, for their history
        let mut per_region: Vec<Vec<usize>> = vec![Vec::new(); self.model.regions.len()];
        for &t in &removed {
            per_region[topo.region_of[t] as usize].push(t);
        }
        // every field concerned must support removal (an empty removal asks), so
        // that no field is cut when a later one would refuse
        for (r, ids) in self.model.regions.iter_mut().zip(&per_region) {
            if let (false, Err(e)) = (ids.is_empty(), r.field.remove_tets(&[])) {
                self.model.cut.topo = Some(topo);
                return Err(e);
            }
        }
        let mut shares: Vec<(usize, [usize; 4], [Vec3; 4])> = Vec::new();
        for (r, region) in self.model.regions.iter().enumerate().filter(|(_, r)| r.prony.is_some()) {
            for &t in &per_region[r] {
                match region.field.tet_forces(t, &self.state.x) {
                    Ok(f) => shares.push((r, self.model.mesh.tets()[t].map(|i| i as usize), f)),
                    Err(e) => {
                        self.model.cut.topo = Some(topo);
                        return Err(e);
                    }
                }
            }
        }
        for (r, ids) in self.model.regions.iter_mut().zip(&per_region) {
            if !ids.is_empty() {
                if let Err(e) = r.field.remove_tets(ids) {
                    self.model.cut.topo = Some(topo);
                    return Err(e);
                }
            }
        }
        let mut removed_mass = 0.0;
        let mut touched: Vec<usize> = Vec::with_capacity(4 * removed.len());
        for &t in &removed {
            topo.alive[t] = false;
            let density = self.model.regions[topo.region_of[t] as usize].density;
            let share = density * self.model.mesh.weighted_volume(t) / 4.0;
            removed_mass += 4.0 * share;
            for &i in &self.model.mesh.tets()[t] {
                let i = i as usize;
                self.model.mass[i] -= share;
                topo.tet_count[i] -= 1;
                touched.push(i);
            }
        }
        topo.n_alive -= removed.len();
        touched.sort_unstable();
        touched.dedup();
        topo.update_surface(self.model.mesh.tets(), &removed, &mut self.model.surface);
        let orphaned: Vec<usize> = touched.iter().copied().filter(|&i| topo.tet_count[i] == 0).collect();
        for &i in &touched {
            if topo.tet_count[i] == 0 {
                self.model.mass[i] = 0.0;
            }
            self.model.inv_mass[i] = if self.model.constraints.is_constrained(i) || self.model.mass[i] == 0.0 {
                0.0
            } else {
                1.0 / self.model.mass[i]
            };
        }
        for &i in &orphaned {
            self.drop_node(i);
        }
        if !orphaned.is_empty() {
            self.model
                .constrained_ids
                .retain(|i| orphaned.binary_search(i).is_err());
            self.model.nodal.retain(|(i, _)| orphaned.binary_search(i).is_err());
        }
        for (r, nodes, f) in &shares {
            if let Some(p) = &mut self.model.regions[*r].prony {
                p.remove_share(nodes, f);
            }
        }
        self.model.surface_loads.drop_tets(|t| topo.alive[t]);
        self.model.cut.topo = Some(topo);
        self.model.cut.version += 1;
        self.invalidate();
        Ok(CutReport {
            removed_tets: removed,
            removed_mass,
            orphaned_nodes: orphaned,
            remaining_tets: self.n_tets_alive(),
        })
    }

    /// Drops node `i`, which no tet holds any more, from the dynamics: held where it
    /// is (a free node becomes prescribed at its current displacement), at rest,
    /// with no reaction.
    fn drop_node(&mut self, i: usize) {
        self.state.v[i] = Vec3::zeros();
        self.eval.reaction[i] = Vec3::zeros();
        self.eval.force[i] = Vec3::zeros();
        if !self.model.constraints.is_constrained(i) {
            self.model.constraints.prescribed.push(Prescribed {
                node: i,
                displacement: self.state.x[i] - self.model.mesh.nodes()[i],
                ramp: Ramp::Step,
            });
            self.model.constraints.mask[i] = true;
        }
    }
}
