//! Prints the native probe hashes, one a line: the reference the WebAssembly build must match.

#![forbid(unsafe_code)]

fn main() {
    println!("{}", vtex_synth_wasm::probe().join("\n"));
}
