//! # edgekf-slam — simultaneous distributed localization, mapping and formation control
//!
//! The distributed observer of M. Guo, B. Jayawardhana, J. G. Lee and H. Shim, "Simultaneous distributed
//! localization, mapping and formation control of mobile robots based on local relative measurements",
//! Proc. 21st IFAC World Congress, 2020. Pure computation: no files, no printing, no global RNG.
//!
//! `n` robots keep a formation and follow a moving centroid reference while each robot `i` estimates the whole
//! state `x = [p_1; …; p_n; m_1; …; m_m]` (robots and static landmarks) from its own relative measurements and
//! consensus with its neighbours — so a robot that never sees a landmark still learns where it is.
//!
//! - [`model`]: graphs, `H_i` (eqs. 16–17), the control (eqs. 3–4, 11) and the closed loop (eq. 14);
//! - [`linalg`]: the orthogonal Kalman decomposition (eq. 18), eigenvalues;
//! - [`care`]: the CARE (eq. 20) by the Hamiltonian sign function + Newton–Kleinman, with verification;
//! - [`observer`]: the observer gains (eq. 19), the CARE as printed, the error system (eq. 21);
//! - [`theorem`]: the conditions of Theorem 1 (eqs. 24–25) and the spectral abscissa;
//! - [`disturbance`]: the bounded `L²` disturbances;
//! - [`spec`]: the scenario file and its validation into [`Scenario`];
//! - [`sim`]: RK4 simulation returning a [`Trajectory`].
//!
//! ```
//! use edgekf_slam::{ScenarioSpec, sim};
//! let spec: ScenarioSpec = serde_json::from_str(r#"{
//!   "name": "two", "robots": [[0,0],[1,0]], "landmarks": [[2,2]], "desired": [[0,0],[1,0]],
//!   "landmark_sets": [[0],[]],
//!   "graphs": {"communication": [[1,-1],[-1,1]], "measurement": [[1,-1],[-1,1]], "formation": [[1,-1],[-1,1]]},
//!   "gains": {"k1": 1, "k2": 1, "gamma": 2}, "observer": {"q": 3, "r": 1},
//!   "centroid": {"start": [0.5, 0], "velocity": [0, 0]}, "initial_estimates": "origin",
//!   "time": {"horizon": 1, "step": 0.01, "output_every": 0.1}
//! }"#).unwrap();
//! let sc = spec.validate().unwrap();
//! let traj = sim::simulate(&sc);
//! assert_eq!(traj.times.len(), 11);
//! ```
#![warn(missing_docs)]

pub mod care;
pub mod disturbance;
pub mod graph;
pub mod linalg;
pub mod model;
pub mod observer;
pub mod sim;
pub mod spec;
pub mod theorem;

pub use disturbance::Disturbance;
pub use model::Model;
pub use observer::{ConsensusSign, RobotObserver};
pub use sim::{simulate, Trajectory};
pub use spec::{Scenario, ScenarioError, ScenarioSpec, KIND, SCHEMA};
pub use theorem::Theorem1Report;
