/// A link law sees one edge: its current and rest squared lengths, no J.
#[heml_derive::material(name = "bad_spring", link)]
#[energy(k / 2.0 * (l - L).powi(2) * J)]
pub struct BadSpring {
    pub k: f64,
}

fn main() {}
