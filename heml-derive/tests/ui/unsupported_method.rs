/// Only ln, exp, sqrt, abs, powi and powf are differentiable here.
#[heml_derive::material(name = "trig")]
#[energy(mu * (I1 - 3.0).sin())]
pub struct Trig {
    pub mu: f64,
}

fn main() {}
