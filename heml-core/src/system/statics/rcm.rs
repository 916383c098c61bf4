//! Reverse Cuthill–McKee ordering of a tet mesh's nodes, which keeps the stiffness
//! matrix banded so that [`super::banded::BandLdl`] can factor it.

/// Reverse Cuthill–McKee ordering of the nodes (graph of the tets' edges): every
/// node once, each connected component started from a pseudo-peripheral node.
pub(super) fn rcm_order(n: usize, tets: &[[u32; 4]]) -> Vec<usize> {
    let mut adj: Vec<Vec<usize>> = vec![Vec::new(); n];
    for t in tets {
        for &a in t {
            for &b in t {
                if a != b {
                    adj[a as usize].push(b as usize);
                }
            }
        }
    }
    for l in &mut adj {
        l.sort_unstable();
        l.dedup();
    }
    let bfs_last = |start: usize, seen: &mut Vec<bool>, out: &mut Vec<usize>| {
        let first = out.len();
        seen[start] = true;
        out.push(start);
        let mut head = first;
        while head < out.len() {
            let v = out[head];
            head += 1;
            let mut next: Vec<usize> = adj[v].iter().copied().filter(|&w| !seen[w]).collect();
            next.sort_by_key(|&w| adj[w].len());
            for w in next {
                seen[w] = true;
                out.push(w);
            }
        }
        out[out.len() - 1]
    };
    let mut seen = vec![false; n];
    let mut order = Vec::with_capacity(n);
    for s in 0..n {
        if seen[s] {
            continue;
        }
        // a pseudo-peripheral start: the last node of a BFS from s
        let mut probe_seen = seen.clone();
        let mut probe = Vec::new();
        let start = bfs_last(s, &mut probe_seen, &mut probe);
        bfs_last(start, &mut seen, &mut order);
    }
    order.reverse();
    order
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rcm_orders_every_node_once() {
        let tets = [[0u32, 1, 2, 3], [1, 2, 3, 4], [5, 6, 7, 8]];
        let mut o = rcm_order(9, &tets);
        o.sort_unstable();
        assert_eq!(o, (0..9).collect::<Vec<_>>());
    }
}
