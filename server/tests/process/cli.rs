//! The command line: the offline subcommands (`vtex create`, `vtex render`, `vtex info`), and
//! what `vtex serve` tells a person: start-up errors, its help, its log.

use crate::support::*;
use std::process::Command;

fn vtex(args: &[&str]) -> std::process::Output {
    Command::new(BIN).args(args).env("VTEX_LOG", "warn").output().unwrap()
}

#[tokio::test]
async fn create_info_render_agree_with_the_server() {
    let dir = tempdir();
    let data = dir.path().join("data");
    let sample = dir.path().join("sample.png");
    std::fs::write(&sample, sample_png(64, 21)).unwrap();
    let params = r#"{"tiles_x":8,"tiles_y":8,"iterations":10,"seed":1}"#;
    let out = vtex(&[
        "create",
        "--model",
        "chaos-mosaic",
        "--name",
        "cli pebbles",
        "--params",
        params,
        "--input",
        &format!("sample={}", sample.display()),
        "--data-dir",
        data.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let id = String::from_utf8(out.stdout).unwrap().trim().to_string();
    assert!(vtex_synth::bundle::is_valid_id(&id), "{id}");
    assert_eq!(store_files(&data), vec![format!("{id}.vtex")]);

    // --out writes the same bundle to a file.
    let file = dir.path().join("copy.vtex");
    let params_file = dir.path().join("params.json");
    std::fs::write(&params_file, params).unwrap();
    let out = vtex(&[
        "create",
        "--model",
        "chaos-mosaic",
        "--name",
        "cli pebbles",
        "--params",
        &format!("@{}", params_file.display()),
        "--input",
        &format!("sample={}", sample.display()),
        "--out",
        file.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    assert_eq!(String::from_utf8(out.stdout).unwrap().trim(), id);
    assert_eq!(std::fs::read(&file).unwrap(), std::fs::read(data.join(format!("{id}.vtex"))).unwrap());

    let out = vtex(&["info", &id, "--data-dir", data.to_str().unwrap()]);
    let info: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!((info["width"].as_u64(), info["levels"].as_u64()), (Some(512), Some(2)));
    let out = vtex(&["info", "--data-dir", data.to_str().unwrap()]);
    let all: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(all["textures"][0], info);

    // `render` of one tile's rectangle equals the server's tile, byte for byte.
    let raw = dir.path().join("t.rgba");
    let out = vtex(&["render", file.to_str().unwrap(), "--x", "256", "--y", "0", "--out", raw.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let s = Server::spawn(&data, &[]);
    let (_, _, tile) = get_bytes(&client(), &s.tile_url(&id, 0, 1, 0, "rgba")).await;
    assert_eq!(std::fs::read(&raw).unwrap(), tile);
    let png = dir.path().join("r.png");
    let out = vtex(&[
        "render",
        &id,
        "--data-dir",
        data.to_str().unwrap(),
        "--level",
        "1",
        "--x",
        "-10",
        "--width",
        "300",
        "--height",
        "20",
        "--out",
        png.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (300, 20));
}

#[test]
fn bad_input_fails_with_a_message() {
    let dir = tempdir();
    let sample = dir.path().join("bad.png");
    let png = sample_png(64, 1);
    std::fs::write(&sample, &png[..png.len() / 2]).unwrap();
    let out = vtex(&[
        "create",
        "--model",
        "chaos-mosaic",
        "--name",
        "x",
        "--params",
        r#"{"tiles_x":8,"tiles_y":8}"#,
        "--input",
        &format!("sample={}", sample.display()),
        "--data-dir",
        dir.path().join("d").to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("sample"), "{}", String::from_utf8_lossy(&out.stderr));
    let d = dir.path().join("d");
    assert!(!d.exists() || store_files(&d).is_empty(), "nothing stored");
    let out = vtex(&["render", "/nonexistent.vtex", "--out", "/tmp/x.gif"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("gif"));
    let out = vtex(&["create", "--model", "nope", "--name", "x", "--out", "/tmp/never.vtex"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown model `nope`"));
    let out = vtex(&["serve", "--tile-size", "7", "--bind", "127.0.0.1:0", "--data-dir", dir.path().to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("tile size 7"));
}

/// `vtex serve` with `args` that fails to start: its exit status and its stderr. With
/// RUST_BACKTRACE set, as a developer's shell may have it: a failure is still one line.
fn serve_fails(cmd: &mut Command, args: &[&str]) -> (std::process::ExitStatus, String) {
    let out = cmd.arg("serve").args(args).env("RUST_BACKTRACE", "1").env("VTEX_LOG", "info").output().unwrap();
    assert!(!out.status.success(), "vtex serve {args:?} started");
    assert!(out.stdout.is_empty(), "{}", String::from_utf8_lossy(&out.stdout));
    (out.status, String::from_utf8(out.stderr).unwrap())
}

#[test]
fn a_port_in_use_is_named_and_nothing_is_written() {
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = taken.local_addr().unwrap().to_string();
    let dir = tempdir();
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let missing = dir.path().join("missing");
    for data in [&empty, &missing] {
        let (status, stderr) =
            serve_fails(&mut Command::new(BIN), &["--bind", &addr, "--data-dir", data.to_str().unwrap()]);
        assert_eq!(status.code(), Some(1));
        assert_eq!(stderr, format!("error: cannot listen on {addr}: address already in use\n"));
    }
    assert_eq!(std::fs::read_dir(&empty).unwrap().count(), 0, "no demo written into the data directory");
    assert!(!missing.exists(), "the data directory is not even created");
}

#[test]
fn a_data_directory_that_is_a_file_is_named() {
    let dir = tempdir();
    let file = dir.path().join("data");
    std::fs::write(&file, "not a directory").unwrap();
    let args = ["--bind", "127.0.0.1:0", "--data-dir", file.to_str().unwrap()];
    let (status, stderr) = serve_fails(&mut Command::new(BIN), &args);
    assert_eq!(status.code(), Some(1));
    assert_eq!(stderr, format!("error: data directory {} is not a directory\n", file.display()));
    assert_eq!(std::fs::read(&file).unwrap(), b"not a directory");
}

/// A command running `vtex` as a user that file permissions bind: this one, or as root (CI)
/// the `nobody` uid, from a link to the binary in `dir` (made reachable to all).
#[cfg(target_os = "linux")]
fn unprivileged(dir: &std::path::Path) -> Command {
    use std::os::unix::fs::PermissionsExt;
    use std::os::unix::process::CommandExt;
    if !rustix::process::geteuid().is_root() {
        return Command::new(BIN);
    }
    std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o755)).unwrap();
    let bin = dir.join("vtex");
    std::fs::hard_link(BIN, &bin).or_else(|_| std::fs::copy(BIN, &bin).map(drop)).unwrap();
    let mut cmd = Command::new(bin);
    cmd.uid(65534).gid(65534);
    cmd
}

#[cfg(target_os = "linux")]
#[test]
fn an_unreadable_or_unwritable_data_directory_is_named() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempdir();
    let mode =
        |path: &std::path::Path, mode| std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode)).unwrap();
    let data = |name: &str, m| {
        let path = dir.path().join(name);
        std::fs::create_dir(&path).unwrap();
        mode(&path, m);
        path
    };
    let unreadable = data("unreadable", 0o000);
    let unwritable = data("unwritable", 0o555);
    let closed = data("closed", 0o555);
    let uncreatable = closed.join("data");
    let cases = [
        (&unreadable, format!("cannot read data directory {}: permission denied", unreadable.display())),
        (
            &unwritable,
            format!(
                "cannot write to data directory {}: permission denied (--read-only serves it without writing)",
                unwritable.display()
            ),
        ),
        (&uncreatable, format!("cannot create data directory {}: permission denied", uncreatable.display())),
    ];
    for (path, said) in cases {
        let args = ["--bind", "127.0.0.1:0", "--data-dir", path.to_str().unwrap()];
        let (status, stderr) = serve_fails(&mut unprivileged(dir.path()), &args);
        assert_eq!(status.code(), Some(1));
        assert_eq!(stderr, format!("error: {said}\n"));
        let _ = std::fs::remove_file(dir.path().join("vtex"));
    }
    // Read-only, the unwritable directory is served as it is: no demos, no probe left behind.
    let mut cmd = unprivileged(dir.path());
    let mut child = cmd
        .args(["serve", "--bind", "127.0.0.1:0", "--read-only", "--data-dir", unwritable.to_str().unwrap()])
        .env("VTEX_LOG", "warn")
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    std::io::BufRead::read_line(&mut std::io::BufReader::new(child.stdout.take().unwrap()), &mut line).unwrap();
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(line.starts_with("vtex listening on http://127.0.0.1:"), "{line:?}");
    assert_eq!(std::fs::read_dir(&unwritable).unwrap().count(), 0);
    mode(&unreadable, 0o755);
}

/// The lines of `vtex serve`'s help of one kind (`-h` or `--help`).
fn serve_help(flag: &str) -> String {
    let out = vtex(&["serve", flag]);
    assert!(out.status.success());
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn serve_h_is_one_line_an_option_under_headings() {
    use vtex_server::config::heading;
    let short = serve_help("-h");
    for name in [
        heading::NETWORK,
        heading::STORE,
        heading::BUDGETS,
        heading::VIEWER,
        heading::CONNECTIONS,
        heading::WRITES,
        heading::LOGGING,
    ] {
        assert!(short.lines().any(|l| l == format!("{name}:")), "heading {name}:\n{short}");
    }
    let options: Vec<&str> = short.lines().filter(|l| l.trim_start().starts_with("--")).collect();
    assert!(options.len() >= 30, "every option is listed:\n{short}");
    for line in &options {
        // `--flag <VALUE>`, then its summary on the same line.
        let (_, summary) = line.trim_start().split_once("  ").unwrap_or_else(|| panic!("no summary beside {line:?}"));
        assert!(!summary.trim().is_empty() && line.chars().count() <= 120, "{line:?}");
    }
    assert!(short.lines().count() <= options.len() + 25, "nothing but the options and their headings:\n{short}");
    assert!(!short.contains("[env:"), "environment variables are named in --help only:\n{short}");
}

#[test]
fn serve_help_shows_defaults_and_environment_by_value_not_code_names() {
    let long = serve_help("--help");
    assert!(long.contains("[default: 127.0.0.1:8080]") && long.contains("[env: VTEX_BIND]"), "{long}");
    // Every option names its variable: VTEX_ and its name in capitals.
    let cmd = <vtex_server::cli::Cli as clap::CommandFactory>::command();
    let serve = cmd.find_subcommand("serve").unwrap();
    for arg in serve.get_arguments().filter_map(|a| a.get_long()).filter(|l| *l != "help") {
        let env = format!("[env: VTEX_{}]", arg.to_uppercase().replace('-', "_"));
        assert!(long.contains(&env), "--{arg}: {env}");
    }
    // Capitals joined by underscores are environment variables (vtex's, the log's, and the
    // object store client's), never a constant of the code.
    let words = long.split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'));
    for word in words.filter(|w| w.contains('_') && w.chars().any(|c| c.is_ascii_uppercase())) {
        let known = ["RUST_LOG", "NO_COLOR"].contains(&word) || word.starts_with("AWS_");
        assert!(word.starts_with("VTEX_") || known, "`{word}` in:\n{long}");
    }
    assert!(!long.contains("[`"), "no doc-comment link syntax:\n{long}");
}

/// Requests of several kinds, each by its path: an API document, a tile (the fast path) and a
/// request refused before routing.
async fn a_few_requests(s: &Server) -> Vec<(String, u16, usize)> {
    let id = put(&client(), s, &mosaic(32, 4, 3)).await;
    let mut done = Vec::new();
    for path in
        ["/healthz".to_string(), format!("/api/v1/textures/{id}/tiles/0/0/0.png"), format!("/api/v1/textures/{id}")]
    {
        let (status, _, body) = get_bytes(&client(), &s.url(&path)).await;
        done.push((path, status, body.len()));
    }
    let refused = raw_request(
        &s.addr,
        b"GET /healthz?a=1&b=2&c=3&d=4&e=5&f=6&g=7&h=8 HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n",
    );
    assert!(refused.starts_with("HTTP/1.1 400"), "{refused}");
    done.push(("/healthz".into(), 400, 0));
    done
}

#[tokio::test]
async fn the_log_has_no_colours_and_lines_per_request_only_as_an_access_log() {
    let dir = tempdir();
    let s = Server::spawn(dir.path(), &[]);
    let quiet = a_few_requests(&s).await;
    let log = s.log_text();
    assert!(log.contains("serving") && !log.contains('\x1b'), "plain text in a file:\n{log}");
    for (path, _, _) in &quiet {
        assert!(!log.contains(path.as_str()), "no line for {path} by default:\n{log}");
    }
    drop(s);

    let dir = tempdir();
    let s = Server::spawn(dir.path(), &["--access-log"]);
    let done = a_few_requests(&s).await;
    let upload = 1;
    let lines = || -> Vec<String> {
        let log = s.log_text();
        log.lines().filter(|l| l.contains("vtex::access")).map(String::from).collect()
    };
    // A line is written once its body is sent, perhaps just after the client has it.
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    while lines().len() < done.len() + upload && std::time::Instant::now() < deadline {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let lines = lines();
    assert_eq!(lines.len(), done.len() + upload, "one line per request:\n{}", lines.join("\n"));
    let line_of = |fields: &str| {
        let found: Vec<&String> = lines.iter().filter(|l| l.contains(fields)).collect();
        assert_eq!(found.len(), 1, "one line with {fields}:\n{}", lines.join("\n"));
        found[0].clone()
    };
    line_of("method=POST path=/api/v1/textures status=201 ");
    for (path, status, bytes) in &done {
        let line = line_of(&format!("method=GET path={path} status={status} "));
        assert!(line.contains(" INFO ") && line.contains("latency_us=") && !line.contains('\x1b'), "{line}");
        if *status == 200 {
            assert!(line.contains(&format!(" bytes={bytes} ")), "the body's {bytes} bytes: {line}");
        }
    }
}

/// On a terminal (here `script`'s pseudo-terminal) the log is coloured, unless `NO_COLOR` is set.
#[cfg(target_os = "linux")]
#[test]
fn colours_only_on_a_terminal_and_never_with_no_color() {
    let dir = tempdir();
    let on_terminal = |no_color: Option<&str>| {
        let serve = format!("timeout 3 {BIN} serve --bind 127.0.0.1:0 --no-demos --data-dir {}", dir.path().display());
        let mut cmd = Command::new("script");
        cmd.args(["-qc", &serve, "/dev/null"]).env("VTEX_LOG", "info").env_remove("NO_COLOR");
        if let Some(v) = no_color {
            cmd.env("NO_COLOR", v);
        }
        String::from_utf8_lossy(&cmd.output().unwrap().stdout).into_owned()
    };
    let coloured = on_terminal(None);
    assert!(coloured.contains("store opened") && coloured.contains('\x1b'), "{coloured}");
    let plain = on_terminal(Some("1"));
    assert!(plain.contains("store opened") && !plain.contains('\x1b'), "{plain}");
}
