/// `powi` takes an integer literal; fractional powers use `powf`.
#[heml_derive::material(name = "half_power")]
#[energy(mu * I1bar.powi(1.5))]
pub struct HalfPower {
    pub mu: f64,
}

fn main() {}
