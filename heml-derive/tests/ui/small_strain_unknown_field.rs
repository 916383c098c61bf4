/// A small-strain mapping that sets a field the law does not have.
#[heml_derive::material(name = "misnamed")]
#[energy(mu / 2.0 * (I1bar - 3.0) + kappa / 2.0 * (J - 1.0).powi(2))]
#[small_strain(mu = mu0, bulk = K0)]
pub struct Misnamed {
    pub mu: f64,
    pub kappa: f64,
}

fn main() {}
