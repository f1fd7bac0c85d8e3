//! The viewer built into the real binary: fingerprinted and cached.

use crate::support::*;

#[tokio::test]
async fn the_viewer_is_built_in_fingerprinted_and_cached() {
    let dir = tempdir();
    // Without VTEX_WEB_DIR (the harness sets one): the copy built into the binary.
    let s = Server::spawn_under(&["env", "-u", "VTEX_WEB_DIR"], dir.path(), &[], &[]);
    let c = client();
    let dist = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../client-web/dist");
    let (st, h, page) = get_with(&c, &s.url("/"), &[]).await;
    let page = String::from_utf8(page).unwrap();
    if !dist.join("index.html").is_file() {
        assert_eq!(st, 404);
        assert!(page.contains("npm run build"), "a binary built without the viewer says how to build it: {page}");
        return;
    }
    assert_eq!(st, 200);
    assert_eq!(h["cache-control"], "no-cache");
    let (st, _, _) = get_with(&c, &s.url("/"), &[("if-none-match", h["etag"].to_str().unwrap())]).await;
    assert_eq!(st, 304);
    let main = page
        .split('"')
        .find(|p| p.starts_with("assets/") && p.ends_with("/viewer/main.js"))
        .unwrap_or_else(|| panic!("the page names its fingerprinted script, relatively (a proxy's sub-path): {page}"));
    let (st, h, body) = get_with(&c, &s.url(&format!("/{main}")), &[]).await;
    assert_eq!(st, 200);
    assert_eq!(h["cache-control"], "public, max-age=31536000, immutable");
    assert_eq!(h["content-type"], "text/javascript; charset=utf-8");
    assert_eq!(body, std::fs::read(dist.join("viewer/main.js")).unwrap(), "the built-in script is the build's");
    // Modules import each other relatively, across the build's folders: inside the same
    // fingerprinted directory.
    for (module, file) in [("/viewer/pyramid.js", "viewer/pyramid.js"), ("/shared/batch.js", "shared/batch.js")] {
        let url = format!("/{}", main.replace("/viewer/main.js", module));
        assert_eq!(get_with(&c, &s.url(&url), &[]).await.2, std::fs::read(dist.join(file)).unwrap(), "{url}");
    }
    let (st, h, _) = get_with(&c, &s.url("/viewer/main.js"), &[]).await;
    assert_eq!((st, h["cache-control"].to_str().unwrap()), (200, "no-cache"));
    let other = get_with(&c, &s.url("/assets/0123456789abcdef/viewer/main.js"), &[]).await.0;
    assert_eq!(other, 404, "another build's assets");
}
