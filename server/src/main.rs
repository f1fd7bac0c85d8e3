fn main() {
    eprintln!("vtex {}", env!("CARGO_PKG_VERSION"));
}
