//! Key expressions (`docs/formats.md`). Every key starts with `edgekf/<swarm>` (flag `--swarm`,
//! default `edgekf`), so that several swarms can share a network; the scenario's hash is in
//! every message (not in the key), so that a process of another scenario is heard and refused
//! by name rather than ignored.

/// The keys of one swarm.
#[derive(Debug, Clone)]
pub struct Keys {
    prefix: String,
}

impl Keys {
    /// The keys of swarm `swarm`.
    pub fn new(swarm: &str) -> Self {
        Self {
            prefix: format!("edgekf/{swarm}"),
        }
    }

    /// World → agent i: its sensing of each step.
    pub fn sensing(&self, i: usize) -> String {
        format!("{}/world/sensing/{i}", self.prefix)
    }

    /// World → every agent: start and stop.
    pub fn control(&self) -> String {
        format!("{}/world/control", self.prefix)
    }

    /// Agent i → world: its output of each step (inputs and reports).
    pub fn output(&self, i: usize) -> String {
        format!("{}/agent/{i}/output", self.prefix)
    }

    /// Every agent's output (the world's subscription).
    pub fn outputs(&self) -> String {
        format!("{}/agent/*/output", self.prefix)
    }

    /// Agent i → its neighbours, over the mesh: its input `u^i_k`.
    pub fn input(&self, i: usize) -> String {
        format!("{}/agent/{i}/input", self.prefix)
    }

    /// Agent i → its neighbours, over the mesh: its in-step message (GA-RKF).
    pub fn exchange(&self, i: usize) -> String {
        format!("{}/agent/{i}/exchange", self.prefix)
    }

    /// Everything agent i sends on the mesh: input, exchange and hello (one subscription per
    /// neighbour).
    pub fn mesh_of(&self, i: usize) -> String {
        format!("{}/agent/{i}/*", self.prefix)
    }

    /// Agent i → its neighbours, over the mesh, before the start: "I am here".
    pub fn hello(&self, i: usize) -> String {
        format!("{}/agent/{i}/hello", self.prefix)
    }

    /// Every agent's hello (the world's subscription: an agent also says hello to the world
    /// once it sees it, so that the world refuses an agent of another scenario by name at once).
    pub fn hellos(&self) -> String {
        format!("{}/agent/*/hello", self.prefix)
    }

    /// Agent i → world: "I hear every neighbour" (and, at the end, its link statistics).
    pub fn status(&self, i: usize) -> String {
        format!("{}/agent/{i}/status", self.prefix)
    }

    /// Every agent's status (the world's subscription).
    pub fn statuses(&self) -> String {
        format!("{}/agent/*/status", self.prefix)
    }

    /// Liveliness token of agent i.
    pub fn alive_agent(&self, i: usize) -> String {
        format!("{}/alive/agent/{i}", self.prefix)
    }

    /// Every agent's liveliness token.
    pub fn alive_agents(&self) -> String {
        format!("{}/alive/agent/*", self.prefix)
    }

    /// Liveliness token of the world.
    pub fn alive_world(&self) -> String {
        format!("{}/alive/world", self.prefix)
    }

    /// The agent id at the end of a key `…/agent/<i>/…` or `…/alive/agent/<i>`.
    pub fn agent_of(key: &str) -> Option<usize> {
        let mut parts = key.split('/');
        while let Some(p) = parts.next() {
            if p == "agent" {
                return parts.next()?.parse().ok();
            }
        }
        None
    }
}
