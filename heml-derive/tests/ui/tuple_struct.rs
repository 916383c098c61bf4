/// Parameters need names.
#[heml_derive::material(name = "tuple")]
#[energy(I1 - 3.0)]
pub struct Tuple(pub f64);

fn main() {}
