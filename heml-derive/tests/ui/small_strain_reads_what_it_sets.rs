/// A small-strain mapping that reads a parameter it sets (a cycle).
#[heml_derive::material(name = "cyclic")]
#[energy(mu / 2.0 * (I1bar - 3.0) + kappa / 2.0 * (J - 1.0).powi(2))]
#[small_strain(mu = mu0, kappa = K0 - 2.0 / 3.0 * mu)]
pub struct Cyclic {
    pub mu: f64,
    pub kappa: f64,
}

fn main() {}
