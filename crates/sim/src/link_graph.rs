//! The link graph of a [`SpringTopology`] (fur thesis §3.4.1): its springs and sticks as one
//! undirected link list, each mass's incident links, and the hair forest found by breadth-first
//! search from the anchored root masses — each mass's depth from the skin and the link it hangs
//! from (a stick's far end always hangs from that stick).
//!
//! The topology was validated when it was decoded or built; [`LinkGraph::build`] re-checks the
//! few structural assumptions the solvers make and reports violations as
//! [`SimError::InvalidInput`]. Everything downstream of it trusts the graph.

use std::collections::VecDeque;

use furbake_formats::sections::spring_topology::SpringTopology;

use crate::SimError;
use crate::sentinel::NONE;

/// One undirected link: a spring, or a stick (rigid in the stick solver; `k` is then unused).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Link {
    /// Both ends, topology indices; for a stick, `[near, far]` as seen from the skin.
    pub ends: [u32; 2],
    /// Rest length, metres.
    pub rest: f32,
    /// Hooke constant, N/m (eq. 3.23).
    pub k: f32,
    /// Viscosity constant, N·s/m (eq. 3.24).
    pub c: f32,
    pub stick: bool,
}

impl Link {
    /// The end that is not mass `i`.
    #[inline]
    pub fn other_end(&self, i: usize) -> usize {
        (if self.ends[0] as usize == i { self.ends[1] } else { self.ends[0] }) as usize
    }
}

/// A checked topology's links, incidence and hair forest.
pub(crate) struct LinkGraph<'t> {
    pub topo: &'t SpringTopology,
    /// Springs (topology order), then sticks (topology order).
    pub links: Vec<Link>,
    /// CSR: the links incident to mass `i` are `incident[incident_start[i]..incident_start[i + 1]]`,
    /// in link order.
    incident_start: Vec<u32>,
    incident: Vec<u32>,
    /// Per mass: breadth-first depth from the anchored masses (0 for them; 1 for a free mass not
    /// connected to the skin, which floats).
    pub depth: Vec<u32>,
    /// Per mass: the link it hangs from (NONE for anchored and unconnected masses).
    pub parent_link: Vec<u32>,
}

impl<'t> LinkGraph<'t> {
    /// Checks `t`, gathers its links and finds its hair forest.
    pub fn build(t: &'t SpringTopology) -> Result<LinkGraph<'t>, SimError> {
        check_topology(t)?;
        let links = gather_links(t)?;
        let (incident_start, incident) = index_incidence(t.mass_kg.len(), &links);
        let mut graph =
            LinkGraph { topo: t, links, incident_start, incident, depth: Vec::new(), parent_link: Vec::new() };
        graph.hang_from_anchors()?;
        Ok(graph)
    }

    /// Number of masses.
    pub fn len(&self) -> usize {
        self.topo.mass_kg.len()
    }

    #[inline]
    pub fn anchored(&self, i: usize) -> bool {
        self.topo.mass_anchored[i] != 0
    }

    /// The links incident to mass `i`, in link order.
    #[inline]
    pub fn incident(&self, i: usize) -> &[u32] {
        &self.incident[self.incident_start[i] as usize..self.incident_start[i + 1] as usize]
    }

    /// Breadth-first search from the anchored masses: depth and parent link of every mass. Sticks
    /// are only followed from their near end, and must be how their far end is reached.
    fn hang_from_anchors(&mut self) -> Result<(), SimError> {
        let n = self.len();
        let mut depth = vec![u32::MAX; n];
        let mut parent_link = vec![NONE; n];
        let mut queue = VecDeque::new();
        for (i, d) in depth.iter_mut().enumerate() {
            if self.anchored(i) {
                *d = 0;
                queue.push_back(i);
            }
        }
        let mut stick_child = vec![NONE; n];
        for (li, l) in self.links.iter().enumerate() {
            if l.stick {
                let far = l.ends[1] as usize;
                if self.anchored(far) || stick_child[far] != NONE {
                    return bad(format!("mass {far} is the far end of an anchored or second stick"));
                }
                stick_child[far] = li as u32;
            }
        }
        while let Some(i) = queue.pop_front() {
            for &li in self.incident(i) {
                let l = self.links[li as usize];
                let j = l.other_end(i);
                if depth[j] != u32::MAX {
                    continue;
                }
                // Sticks are only ever followed from their near end.
                if l.stick && l.ends[1] as usize != j {
                    continue;
                }
                depth[j] = depth[i] + 1;
                parent_link[j] = li;
                queue.push_back(j);
            }
        }
        for (i, &stick) in stick_child.iter().enumerate() {
            if stick != NONE && parent_link[i] != stick {
                return bad(format!("stick {stick} does not lead away from the skin"));
            }
        }
        for d in &mut depth {
            if *d == u32::MAX {
                *d = 1; // a free mass not connected to the skin: it floats.
            }
        }
        (self.depth, self.parent_link) = (depth, parent_link);
        Ok(())
    }
}

fn bad<T>(what: String) -> Result<T, SimError> {
    Err(SimError::InvalidInput(what))
}

/// Array lengths agree, indices are in range, masses positive and positions finite.
fn check_topology(t: &SpringTopology) -> Result<(), SimError> {
    let n = t.mass_kg.len();
    let lens = [
        t.mass_rest_positions.len(),
        t.mass_anchored.len(),
        t.spring_ends.len(),
        t.spring_rest_lengths_m.len(),
        t.spring_stiffness_n_per_m.len(),
        t.spring_damping_n_s_per_m.len(),
        t.stick_ends.len(),
        t.stick_lengths_m.len(),
    ];
    if lens[0] != n
        || lens[1] != n
        || lens[3] != lens[2]
        || lens[4] != lens[2]
        || lens[5] != lens[2]
        || lens[7] != lens[6]
    {
        return bad(format!("topology arrays disagree in length: {n} masses, {lens:?}"));
    }
    if n >= NONE as usize {
        return bad("too many masses".into());
    }
    let in_range = |e: &[u32; 2]| (e[0] as usize) < n && (e[1] as usize) < n && e[0] != e[1];
    if !t.spring_ends.iter().all(in_range) || !t.stick_ends.iter().all(in_range) {
        return bad("a spring or stick index is out of range or joins a mass to itself".into());
    }
    if !t.mass_kg.iter().all(|m| m.is_finite() && *m > 0.0)
        || !t.mass_rest_positions.iter().flatten().all(|c| c.is_finite())
    {
        return bad("masses must be positive and positions finite".into());
    }
    Ok(())
}

/// The undirected link list: springs, then sticks (with the topology's stick damping), each in
/// topology order; lengths and constants must be finite and ≥ 0.
fn gather_links(t: &SpringTopology) -> Result<Vec<Link>, SimError> {
    let mut links = Vec::with_capacity(t.spring_ends.len() + t.stick_ends.len());
    for (s, &ends) in t.spring_ends.iter().enumerate() {
        links.push(Link {
            ends,
            rest: t.spring_rest_lengths_m[s],
            k: t.spring_stiffness_n_per_m[s],
            c: t.spring_damping_n_s_per_m[s],
            stick: false,
        });
    }
    let damping = t.params.damping_n_s_per_m;
    for (s, &ends) in t.stick_ends.iter().enumerate() {
        links.push(Link { ends, rest: t.stick_lengths_m[s], k: 0.0, c: damping, stick: true });
    }
    let valid = |x: f32| x.is_finite() && x >= 0.0;
    if !links.iter().all(|l| valid(l.rest) && valid(l.k) && valid(l.c)) {
        return bad("link lengths and constants must be finite and ≥ 0".into());
    }
    Ok(links)
}

/// CSR of the links incident to each of `n` masses, in link order.
fn index_incidence(n: usize, links: &[Link]) -> (Vec<u32>, Vec<u32>) {
    let mut start = vec![0u32; n + 1];
    for l in links {
        start[l.ends[0] as usize + 1] += 1;
        start[l.ends[1] as usize + 1] += 1;
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut incident = vec![0u32; start[n] as usize];
    for (li, l) in links.iter().enumerate() {
        for e in l.ends {
            incident[fill[e as usize] as usize] = li as u32;
            fill[e as usize] += 1;
        }
    }
    (start, incident)
}
