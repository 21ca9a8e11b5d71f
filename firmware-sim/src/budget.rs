pub fn report(_: Option<&std::path::Path>, _: Option<&std::path::Path>) -> Result<Report, String> { Err("todo".into()) }
#[derive(Debug)] pub struct Report; impl Report { pub fn json(&self) -> String { String::new() } pub fn text(&self) -> String { String::new() } }
