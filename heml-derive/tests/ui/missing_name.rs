/// The registry name is required.
#[heml_derive::material(no_inversion_fix)]
#[energy(mu * (I1 - 3.0))]
pub struct Anonymous {
    pub mu: f64,
}

fn main() {}
