/// Parameters are f64.
#[heml_derive::material(name = "integer_param")]
#[energy(mu * (I1 - 3.0))]
pub struct IntegerParam {
    pub mu: f64,
    pub order: u32,
}

fn main() {}
