//! The `edgekf` command-line program.
mod plot;

fn main() {
    plot::register_fonts();
}
