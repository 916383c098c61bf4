/// A declared volumetric energy that reads an invariant: U depends on J only.
#[heml_derive::material(name = "leaky")]
#[energy(mu / 2.0 * (I1bar - 3.0) + kappa / 2.0 * (J - 1.0).powi(2))]
#[volumetric(kappa / 2.0 * (J - 1.0).powi(2) + mu * (I1bar - 3.0))]
pub struct Leaky {
    pub mu: f64,
    pub kappa: f64,
}

fn main() {}
