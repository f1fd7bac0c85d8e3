//! The transport a real `vtex serve` runs comes from `--send` or `VTEX_SEND`.

use crate::support::*;

/// `--send` and `VTEX_SEND` choose the transport with the precedence of every setting (the flag
/// beats the environment), and a name that is not a transport is refused before serving.
#[test]
fn the_transport_comes_from_the_flag_or_vtex_send() {
    let dir = tempdir();
    let s = Server::spawn_env(dir.path(), &[], &[("VTEX_SEND", "copy")]);
    assert!(s.log_text().contains("send=copy"), "{}", s.log_text());
    drop(s);
    let s = Server::spawn_env(dir.path(), &["--send", "copy"], &[("VTEX_SEND", "splice")]);
    assert!(s.log_text().contains("send=copy"), "the flag wins: {}", s.log_text());
    drop(s);
    let refused = |env: &[(&str, &str)], extra: &[&str]| {
        let out = std::process::Command::new(BIN)
            .args(["serve", "--bind", "127.0.0.1:0", "--no-demos"])
            .args(extra)
            .envs(env.iter().copied())
            .output()
            .unwrap();
        assert!(!out.status.success());
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let err = refused(&[], &["--send", "sendfile"]);
    assert!(err.contains("expected `copy` or `splice`"), "{err}");
    if cfg!(target_os = "linux") {
        let s = Server::spawn_env(dir.path(), &[], &[("VTEX_SEND", "splice")]);
        assert!(s.log_text().contains("send=splice"), "{}", s.log_text());
    } else {
        let err = refused(&[("VTEX_SEND", "splice")], &[]);
        assert!(err.contains("needs Linux"), "{err}");
    }
}
