//! Sensing graphs: undirected links, directed edges in incidence order, incidence and Laplacian
//! matrices, neighbourhoods.
//!
//! Conventions (DESIGN.md, contract): agents are `0..N`; a directed edge `(i, j)` means *agent i
//! measures agent j* and carries the state `z_ij = z_i − z_j` (thesis eq. 4.5). Every undirected
//! link `{i, j}` gives the two directed edges `(i, j)` and `(j, i)`. Directed edges are ordered by
//! measuring agent `i` ascending, then `j` ascending; column `e = (i, j)` of the incidence matrix
//! `B` (N × M) has `+1` in row `i` and `−1` in row `j`, so `x = (Bᵀ ⊗ I_D) z` stacks all `z_ij`
//! (thesis eq. 5.3), and the edges of agent `i` are contiguous: they are the columns of `B_i`
//! (thesis §5.3).

use std::ops::Range;

use nalgebra::DMatrix;

/// Errors building a [`Graph`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum GraphError {
    /// A link refers to an agent outside `0..N`.
    #[error("link {index} = ({i}, {j}) refers to agent {bad}, but agents are 0..{n}")]
    AgentOutOfRange {
        /// Position of the link in the input list.
        index: usize,
        /// First endpoint.
        i: usize,
        /// Second endpoint.
        j: usize,
        /// The offending agent.
        bad: usize,
        /// Number of agents.
        n: usize,
    },
    /// A link joins an agent to itself.
    #[error("link {index} joins agent {i} to itself")]
    SelfLoop {
        /// Position of the link in the input list.
        index: usize,
        /// The agent.
        i: usize,
    },
    /// The same undirected link appears twice.
    #[error("link ({i}, {j}) appears more than once")]
    DuplicateLink {
        /// Smaller endpoint.
        i: usize,
        /// Larger endpoint.
        j: usize,
    },
    /// The graph is not connected.
    #[error("the graph is not connected: agent {unreached} cannot be reached from agent 0")]
    Disconnected {
        /// An agent not reachable from agent 0.
        unreached: usize,
    },
    /// Fewer than two agents.
    #[error("a sensing graph needs at least 2 agents, got {n}")]
    TooFewAgents {
        /// Number of agents.
        n: usize,
    },
}

/// An undirected, connected sensing graph with its directed edges in incidence order.
#[derive(Debug, Clone, PartialEq)]
pub struct Graph {
    n: usize,
    links: Vec<(usize, usize)>,
    edges: Vec<(usize, usize)>,
    edge_link: Vec<usize>,
    reverse: Vec<usize>,
    agent_edges: Vec<Range<usize>>,
}

impl Graph {
    /// Builds a graph on `n` agents from undirected links (any order, either orientation).
    ///
    /// # Errors
    /// [`GraphError`] when a link is out of range, a self loop or a duplicate, or when the graph is
    /// not connected.
    ///
    /// ```
    /// use edgekf::graph::Graph;
    /// let g = Graph::new(3, &[(0, 1), (1, 2), (2, 0)]).unwrap();
    /// assert_eq!(g.edges(), &[(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)]);
    /// ```
    pub fn new(n: usize, links: &[(usize, usize)]) -> Result<Self, GraphError> {
        if n < 2 {
            return Err(GraphError::TooFewAgents { n });
        }
        let mut sorted = Vec::with_capacity(links.len());
        for (index, &(i, j)) in links.iter().enumerate() {
            for bad in [i, j] {
                if bad >= n {
                    return Err(GraphError::AgentOutOfRange {
                        index,
                        i,
                        j,
                        bad,
                        n,
                    });
                }
            }
            if i == j {
                return Err(GraphError::SelfLoop { index, i });
            }
            sorted.push((i.min(j), i.max(j)));
        }
        sorted.sort_unstable();
        for w in sorted.windows(2) {
            if w[0] == w[1] {
                return Err(GraphError::DuplicateLink {
                    i: w[0].0,
                    j: w[0].1,
                });
            }
        }
        let mut edges: Vec<(usize, usize)> =
            sorted.iter().flat_map(|&(i, j)| [(i, j), (j, i)]).collect();
        edges.sort_unstable();
        let edge_link = edges
            .iter()
            .map(|&(i, j)| {
                sorted
                    .binary_search(&(i.min(j), i.max(j)))
                    .expect("edge comes from a link")
            })
            .collect();
        let reverse = edges
            .iter()
            .map(|&(i, j)| {
                edges
                    .binary_search(&(j, i))
                    .expect("both orientations present")
            })
            .collect();
        let mut agent_edges = Vec::with_capacity(n);
        let mut start = 0;
        for a in 0..n {
            let end = start + edges[start..].iter().take_while(|e| e.0 == a).count();
            agent_edges.push(start..end);
            start = end;
        }
        let g = Self {
            n,
            links: sorted,
            edges,
            edge_link,
            reverse,
            agent_edges,
        };
        if let Some(unreached) = g.first_unreached() {
            return Err(GraphError::Disconnected { unreached });
        }
        Ok(g)
    }

    /// The complete graph on `n` agents.
    ///
    /// # Errors
    /// [`GraphError::TooFewAgents`] for `n < 2`.
    pub fn complete(n: usize) -> Result<Self, GraphError> {
        let links: Vec<_> = (0..n)
            .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
            .collect();
        Self::new(n, &links)
    }

    fn first_unreached(&self) -> Option<usize> {
        let mut seen = vec![false; self.n];
        let mut stack = vec![0];
        seen[0] = true;
        while let Some(a) = stack.pop() {
            for &(_, b) in &self.edges[self.agent_edges[a].clone()] {
                if !seen[b] {
                    seen[b] = true;
                    stack.push(b);
                }
            }
        }
        seen.iter().position(|s| !s)
    }

    /// Number of agents N.
    pub fn agents(&self) -> usize {
        self.n
    }

    /// Undirected links `(i, j)` with `i < j`, sorted.
    pub fn links(&self) -> &[(usize, usize)] {
        &self.links
    }

    /// Directed edges in incidence order (M = 2 × links).
    pub fn edges(&self) -> &[(usize, usize)] {
        &self.edges
    }

    /// Number of directed edges M.
    pub fn num_edges(&self) -> usize {
        self.edges.len()
    }

    /// Index of the undirected link of directed edge `e`.
    pub fn link_of(&self, e: usize) -> usize {
        self.edge_link[e]
    }

    /// Index of the reversed edge `(j, i)` of edge `e = (i, j)`.
    pub fn reverse_of(&self, e: usize) -> usize {
        self.reverse[e]
    }

    /// The directed edges measured by agent `i` (contiguous in incidence order): the columns of
    /// `B_i`.
    pub fn edges_of(&self, i: usize) -> Range<usize> {
        self.agent_edges[i].clone()
    }

    /// Neighbours of agent `i`, ascending.
    pub fn neighbours(&self, i: usize) -> impl Iterator<Item = usize> + '_ {
        self.edges[self.agent_edges[i].clone()].iter().map(|e| e.1)
    }

    /// Index of directed edge `(i, j)`, if present.
    pub fn edge_index(&self, i: usize, j: usize) -> Option<usize> {
        self.edges.binary_search(&(i, j)).ok()
    }

    /// Whether agents `i` and `j` are linked.
    pub fn has_link(&self, i: usize, j: usize) -> bool {
        self.edge_index(i, j).is_some()
    }

    /// The incidence matrix `B` (N × M) in our order.
    pub fn incidence(&self) -> DMatrix<f64> {
        let mut b = DMatrix::zeros(self.n, self.edges.len());
        for (e, &(i, j)) in self.edges.iter().enumerate() {
            b[(i, e)] = 1.0;
            b[(j, e)] = -1.0;
        }
        b
    }

    /// The generalized Laplacian `L = Σ_links w_l (e_i − e_j)(e_i − e_j)ᵀ` (thesis Def. 2.1,
    /// eq. 3.4) for one weight per undirected link (in [`Graph::links`] order). Weights may be
    /// negative.
    ///
    /// # Panics
    /// If `weights.len()` differs from the number of links.
    pub fn laplacian(&self, weights: &[f64]) -> DMatrix<f64> {
        assert_eq!(weights.len(), self.links.len(), "one weight per link");
        let mut l = DMatrix::zeros(self.n, self.n);
        for (&(i, j), &w) in self.links.iter().zip(weights) {
            l[(i, i)] += w;
            l[(j, j)] += w;
            l[(i, j)] -= w;
            l[(j, i)] -= w;
        }
        l
    }

    /// `b_eᵀ b_f` for directed edges `e`, `f`: the (e, f) entry of `BᵀB`.
    pub fn incidence_gram(&self, e: usize, f: usize) -> f64 {
        let (a, b) = self.edges[e];
        let (c, d) = self.edges[f];
        let ind = |x: usize, y: usize| if x == y { 1.0 } else { 0.0 };
        ind(a, c) - ind(a, d) - ind(b, c) + ind(b, d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn incidence_columns_sum_to_zero_and_order_is_contract() {
        let g = Graph::new(4, &[(2, 0), (0, 1), (1, 2), (3, 1)]).unwrap();
        assert_eq!(g.links(), &[(0, 1), (0, 2), (1, 2), (1, 3)]);
        assert_eq!(
            g.edges(),
            &[
                (0, 1),
                (0, 2),
                (1, 0),
                (1, 2),
                (1, 3),
                (2, 0),
                (2, 1),
                (3, 1)
            ]
        );
        let b = g.incidence();
        for e in 0..g.num_edges() {
            assert_eq!(b.column(e).sum(), 0.0);
            assert_eq!(g.edges()[g.reverse_of(e)], (g.edges()[e].1, g.edges()[e].0));
        }
        assert_eq!(g.edges_of(1), 2..5);
        assert_eq!(g.neighbours(1).collect::<Vec<_>>(), vec![0, 2, 3]);
        let gram = b.transpose() * &b;
        for e in 0..g.num_edges() {
            for f in 0..g.num_edges() {
                assert_eq!(gram[(e, f)], g.incidence_gram(e, f));
            }
        }
    }

    #[test]
    fn laplacian_matches_incidence_form() {
        let g = Graph::complete(4).unwrap();
        let w: Vec<f64> = (0..g.links().len()).map(|k| 0.5 + k as f64).collect();
        let l = g.laplacian(&w);
        // L = B diag(w per directed edge) Bᵀ / 2 since each link appears twice.
        let b = g.incidence();
        let wd: Vec<f64> = (0..g.num_edges()).map(|e| w[g.link_of(e)] / 2.0).collect();
        let l2 = &b * DMatrix::from_diagonal(&nalgebra::DVector::from_vec(wd)) * b.transpose();
        assert!((l - l2).amax() < 1e-12);
    }

    #[test]
    fn errors_name_the_problem() {
        assert_eq!(
            Graph::new(3, &[(0, 1), (1, 0)]).unwrap_err().to_string(),
            "link (0, 1) appears more than once"
        );
        assert!(matches!(
            Graph::new(3, &[(0, 1)]),
            Err(GraphError::Disconnected { unreached: 2 })
        ));
        assert!(matches!(
            Graph::new(3, &[(0, 3)]),
            Err(GraphError::AgentOutOfRange { bad: 3, .. })
        ));
        assert!(matches!(
            Graph::new(3, &[(1, 1)]),
            Err(GraphError::SelfLoop { i: 1, .. })
        ));
    }
}
