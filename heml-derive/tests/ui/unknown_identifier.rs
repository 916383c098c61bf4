/// A typo in a parameter name.
#[heml_derive::material(name = "typo")]
#[energy(mu / 2.0 * (I1 - 3.0) + kapa / 2.0 * (J - 1.0).powi(2))]
pub struct Typo {
    pub mu: f64,
    pub kappa: f64,
}

fn main() {}
