//! Shared helpers: the shipped scenarios.
#![allow(dead_code)]

use edgekf_slam::{Scenario, ScenarioSpec};

pub const FIG3: &str = include_str!("../../../../scenarios/slam-fig3.toml");
pub const DISTURBED: &str = include_str!("../../../../scenarios/slam-disturbed.toml");

pub fn spec(text: &str) -> ScenarioSpec {
    ScenarioSpec::from_toml(text).expect("shipped scenario parses")
}

pub fn scenario(text: &str) -> Scenario {
    spec(text).validate().expect("shipped scenario validates")
}
