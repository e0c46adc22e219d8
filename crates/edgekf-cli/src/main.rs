//! The `edgekf` command-line program.
//!
//! (Temporary front end on the `design` branch: only `edgekf design`; the lead's main.rs wires
//! `Command::Design(args) => design::run(&args)`.)
mod design;
mod plot;

use clap::{Parser, Subcommand};

/// Edge-state estimation for distributed formation control.
#[derive(Parser, Debug)]
#[command(name = "edgekf", version)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Design the stress (Laplacian weights) of a framework, check it, write framework.json
    /// and framework.png.
    Design(design::DesignArgs),
}

fn main() -> anyhow::Result<()> {
    plot::register_fonts();
    match Cli::parse().command {
        Command::Design(args) => design::run(&args),
    }
}
