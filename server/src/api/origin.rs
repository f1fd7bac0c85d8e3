//! How clients reach this server and who they are, when proxies stand between: the one place
//! absolute URLs (IIIF ids, TileJSON tile templates, the OpenAPI server, model example links)
//! and the client's address are made.
//!
//! Every absolute URL is [`Origin`] (an extractor; [`origin`] as a function) followed by a path
//! from the API's root: `format!("{origin}/iiif/3/{id}")`. [`Origin`] is, in this order:
//! - `--public-url` when set (`https://example.org/vtex/` gives `https://example.org/vtex`);
//! - else, from a peer in `--trusted-proxies`, what its forwarded headers say: `Forwarded`
//!   (RFC 7239: `host`, `proto`), else `X-Forwarded-Host`, `X-Forwarded-Proto`, with
//!   `X-Forwarded-Port` and `X-Forwarded-Prefix` (the sub-path the proxy strips);
//! - else the request's own `Host` (or HTTP/2 authority), over `http`.
//!
//! From any other peer forwarded headers are ignored, so a client cannot make the server write
//! URLs to a host of its choosing. A chain of trusted proxies is walked from the nearest one
//! (the rightmost `Forwarded` element or `X-Forwarded-For` entry) back to the first address
//! that is not trusted: that is the client ([`client_addr`]), and its `Forwarded` element says
//! how the client addressed the outermost proxy. `X-Forwarded-Host/-Proto/-Port/-Prefix` carry
//! no such chain: their last value, the nearest proxy's, counts. A malformed `Forwarded` is
//! ignored whole; a malformed value of another header is ignored.

use crate::config::ServeConfig;
use crate::config::{PublicUrl, TrustedProxy};
use axum::extract::ConnectInfo;
use axum::http::request::Parts;
use axum::http::uri::Authority;
use axum::http::{header, HeaderMap};
use std::net::{IpAddr, Ipv4Addr, SocketAddr};

/// Whether `ip` is one of the trusted proxies.
fn trusted(proxies: &[TrustedProxy], ip: IpAddr) -> bool {
    proxies.iter().any(|p| p.0.contains(&ip))
}

/// `scheme://host[:port][/prefix]`, without a trailing slash: how clients reach this server.
/// Absolute URLs are it followed by a path from the API's root.
#[derive(Clone, Debug, PartialEq)]
pub struct Origin(String);

impl Origin {
    /// The absolute URL of `path`, a path from the API's root (`/iiif/3/…`).
    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.0)
    }
}

impl std::fmt::Display for Origin {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// How the client of the request `parts` reached this server (see the module's rules).
pub fn origin(cfg: &ServeConfig, parts: &Parts) -> Origin {
    if let Some(PublicUrl(url)) = &cfg.public_url {
        return Origin(url.clone());
    }
    let fwd = forwarded(&cfg.trusted_proxies, peer(parts), &parts.headers);
    let own_host = || {
        let host = parts.headers.get(header::HOST).and_then(|h| Authority::try_from(h.as_bytes()).ok());
        host.or_else(|| parts.uri.authority().cloned())
    };
    let https = fwd.proto.as_deref() == Some("https");
    let (host, port) = match fwd.host.or_else(own_host) {
        Some(a) => (a.host().to_string(), fwd.port.or(a.port_u16())),
        None => ("localhost".to_string(), None),
    };
    let port = port.filter(|&p| p != if https { 443 } else { 80 }).map(|p| format!(":{p}")).unwrap_or_default();
    let prefix = fwd.prefix.unwrap_or_default();
    Origin(format!("{}://{host}{port}{prefix}", if https { "https" } else { "http" }))
}

/// The address of the client of the request `parts`: the one its trusted proxies forwarded for
/// (unspecified, so never loopback, when they say `unknown` or an obfuscated name), else the
/// peer of the connection (unspecified if the request has none).
pub fn client_addr(cfg: &ServeConfig, parts: &Parts) -> IpAddr {
    forwarded(&cfg.trusted_proxies, peer(parts), &parts.headers).client
}

/// The connection's peer, IPv4-mapped IPv6 addresses as IPv4.
fn peer(parts: &Parts) -> Option<IpAddr> {
    parts.extensions.get::<ConnectInfo<SocketAddr>>().map(|c| c.0.ip().to_canonical())
}

const UNKNOWN: IpAddr = IpAddr::V4(Ipv4Addr::UNSPECIFIED);

/// What the forwarded headers of a request say, where they are believed.
struct Forwarded {
    client: IpAddr,
    host: Option<Authority>,
    /// Replaces the port of the host unless the host came from `Forwarded`.
    port: Option<u16>,
    /// `http` or `https`.
    proto: Option<String>,
    /// `/a/b`, or none for the root.
    prefix: Option<String>,
}

/// One proxy's record of the request it received: from whom, for which host, over what.
#[derive(Debug, Default)]
struct Hop {
    client: Option<IpAddr>,
    host: Option<Authority>,
    proto: Option<String>,
}

/// The forwarded headers of a request from `peer`, believed only when it is trusted.
fn forwarded(proxies: &[TrustedProxy], peer: Option<IpAddr>, headers: &HeaderMap) -> Forwarded {
    let alone = |client| Forwarded { client, host: None, port: None, proto: None, prefix: None };
    let Some(peer) = peer else { return alone(UNKNOWN) };
    if !trusted(proxies, peer) {
        return alone(peer);
    }
    // The nearest hop whose client is not itself a trusted proxy.
    let walk = |hops: Vec<Hop>| {
        let mut hops = hops.into_iter().rev().peekable();
        while let Some(hop) = hops.next() {
            if hops.peek().is_none() || !hop.client.is_some_and(|c| trusted(proxies, c)) {
                return Some(hop);
            }
        }
        None
    };
    let from_forwarded = rfc7239_hops(headers).and_then(walk);
    let port_applies = from_forwarded.as_ref().is_none_or(|h| h.host.is_none());
    let hop = from_forwarded.or_else(|| x_forwarded_for_hops(headers).and_then(walk));
    let (client, host, proto) = match hop {
        Some(h) => (h.client.unwrap_or(UNKNOWN), h.host, h.proto),
        None => (peer, None, None),
    };
    Forwarded {
        client,
        host: host.or_else(|| last(headers, "x-forwarded-host").and_then(authority)),
        port: last(headers, "x-forwarded-port").and_then(|p| p.parse().ok()).filter(|_| port_applies),
        proto: proto.or_else(|| last(headers, "x-forwarded-proto").and_then(scheme)),
        prefix: last(headers, "x-forwarded-prefix").and_then(prefix),
    }
}

/// The last value of the comma-separated list in the fields `name`.
fn last<'a>(headers: &'a HeaderMap, name: &str) -> Option<&'a str> {
    let field = headers.get_all(name).iter().next_back()?.to_str().ok()?;
    Some(field.rsplit(',').next()?.trim()).filter(|v| !v.is_empty())
}

/// `host[:port]`, as `Host` takes it.
fn authority(text: &str) -> Option<Authority> {
    Authority::try_from(text).ok().filter(|a| !a.as_str().contains('@') && !a.host().is_empty())
}

/// `http` or `https`, in any case.
fn scheme(text: &str) -> Option<String> {
    let p = text.to_ascii_lowercase();
    matches!(p.as_str(), "http" | "https").then_some(p)
}

/// A path of segments of URL path characters, without `.` or `..` segments, trailing slash
/// dropped; `/` alone is the root, given as none.
fn prefix(text: &str) -> Option<String> {
    let path = text.strip_prefix('/')?.trim_end_matches('/');
    let pchar = |c: char| c.is_ascii_alphanumeric() || "-._~!$&'()*+,;=:@%".contains(c);
    let valid = path.split('/').all(|s| !matches!(s, "" | "." | "..") && s.chars().all(pchar));
    (!path.is_empty() && valid).then(|| format!("/{path}"))
}

/// `X-Forwarded-For`'s addresses, oldest first; none if absent or any entry is not an address.
fn x_forwarded_for_hops(headers: &HeaderMap) -> Option<Vec<Hop>> {
    let mut hops = Vec::new();
    for field in headers.get_all("x-forwarded-for") {
        for entry in field.to_str().ok()?.split(',').map(str::trim).filter(|e| !e.is_empty()) {
            hops.push(Hop { client: Some(node(entry)?), ..Hop::default() });
        }
    }
    (!hops.is_empty()).then_some(hops)
}

/// An address as proxies write it: `192.0.2.1`, `192.0.2.1:4711`, `2001:db8::1` or
/// `[2001:db8::1]:4711`.
fn node(text: &str) -> Option<IpAddr> {
    let ip = text.parse::<IpAddr>().or_else(|_| text.parse::<SocketAddr>().map(|s| s.ip())).ok()?;
    Some(ip.to_canonical())
}

/// The elements of the `Forwarded` fields (RFC 7239 §4), oldest first; none if absent or
/// malformed anywhere (a syntax error, a parameter twice in an element, a `for` that is not a
/// node, a `host` that is not `host[:port]`).
fn rfc7239_hops(headers: &HeaderMap) -> Option<Vec<Hop>> {
    let mut hops = Vec::new();
    for field in headers.get_all(header::FORWARDED) {
        for element in rfc7239_elements(field.to_str().ok()?)? {
            let mut hop = Hop::default();
            for (name, value) in element {
                match name.as_str() {
                    // `unknown` and obfuscated identifiers (`_abc`) name no address.
                    "for" if value == "unknown" || value.starts_with('_') => {}
                    "for" => hop.client = Some(node(&value)?),
                    "host" => hop.host = Some(authority(&value)?),
                    "proto" => hop.proto = scheme(&value),
                    _ => {}
                }
            }
            hops.push(hop);
        }
    }
    (!hops.is_empty()).then_some(hops)
}

/// RFC 7239 §4: `Forwarded = 1#forwarded-element`, `forwarded-element = [ forwarded-pair ] *(
/// ";" [ forwarded-pair ] )`, `forwarded-pair = token "=" ( token / quoted-string )`. Each
/// element as its pairs, names lowercased, values unquoted; none if the text breaks the
/// grammar or repeats a name in an element. Unquoted values may also hold `:`, `[` and `]`, as
/// proxies configured with `host=$http_host` or `for=$remote_addr:$remote_port` write them.
fn rfc7239_elements(text: &str) -> Option<Vec<Vec<(String, String)>>> {
    let tchar = |c: char| c.is_ascii_alphanumeric() || "!#$%&'*+-.^_`|~".contains(c);
    let span = |s: &str, ok: &dyn Fn(char) -> bool| s.find(|c: char| !ok(c)).unwrap_or(s.len());
    let (mut rest, mut elements, mut element) = (text, Vec::new(), Vec::<(String, String)>::new());
    loop {
        rest = rest.trim_start_matches([' ', '\t']);
        if !rest.is_empty() && !rest.starts_with([',', ';']) {
            let n = span(rest, &tchar);
            let name = rest[..n].to_ascii_lowercase();
            rest = rest[n..].strip_prefix('=').filter(|_| n > 0)?;
            let value = match rest.strip_prefix('"') {
                Some(quoted) => {
                    let (value, after) = unquote(quoted)?;
                    rest = after;
                    value
                }
                None => {
                    let n = span(rest, &|c| tchar(c) || matches!(c, ':' | '[' | ']'));
                    let value = rest[..n].to_string();
                    rest = &rest[n..];
                    value
                }
            };
            if value.is_empty() || element.iter().any(|(k, _)| *k == name) {
                return None;
            }
            element.push((name, value));
            rest = rest.trim_start_matches([' ', '\t']);
        }
        match rest.chars().next() {
            None | Some(',') => {
                if !element.is_empty() {
                    elements.push(std::mem::take(&mut element));
                }
                if rest.is_empty() {
                    return Some(elements);
                }
            }
            Some(';') => {}
            Some(_) => return None,
        }
        rest = &rest[1..];
    }
}

/// The quoted-string (RFC 9110 §5.6.4) whose opening quote was just read: its value and what
/// follows the closing quote.
fn unquote(text: &str) -> Option<(String, &str)> {
    let mut value = String::new();
    let mut chars = text.char_indices();
    while let Some((i, c)) = chars.next() {
        match c {
            '"' => return Some((value, &text[i + 1..])),
            '\\' => value.push(chars.next()?.1),
            c if c == '\t' || (' '..='~').contains(&c) => value.push(c),
            _ => return None,
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::http::Request;
    use clap::Parser;

    #[derive(Parser)]
    struct Serve {
        #[command(flatten)]
        cfg: ServeConfig,
    }

    fn cfg(args: &[&str]) -> ServeConfig {
        Serve::try_parse_from(std::iter::once("vtex").chain(args.iter().copied())).unwrap().cfg
    }

    /// A request from `peer` with `headers`, as the front service hands it on.
    fn request(peer: &str, headers: &[(&str, &str)]) -> Parts {
        let mut req = Request::get("/iiif/3/x/info.json");
        for (k, v) in headers {
            req = req.header(*k, *v);
        }
        let (mut parts, ()) = req.body(()).unwrap().into_parts();
        parts.extensions.insert(ConnectInfo(peer.parse::<SocketAddr>().unwrap()));
        parts
    }

    fn url(cfg: &ServeConfig, peer: &str, headers: &[(&str, &str)]) -> String {
        origin(cfg, &request(peer, headers)).to_string()
    }

    const SPOOF: &[(&str, &str)] = &[
        ("host", "vtex.internal:8080"),
        ("forwarded", "for=192.0.2.1;host=evil.example;proto=https"),
        ("x-forwarded-for", "192.0.2.1"),
        ("x-forwarded-host", "evil.example"),
        ("x-forwarded-proto", "https"),
        ("x-forwarded-port", "8443"),
        ("x-forwarded-prefix", "/evil"),
    ];

    #[test]
    fn forwarded_headers_from_an_untrusted_peer_are_ignored() {
        let none = cfg(&[]);
        assert_eq!(url(&none, "203.0.113.9:5000", SPOOF), "http://vtex.internal:8080");
        assert_eq!(client_addr(&none, &request("203.0.113.9:5000", SPOOF)), "203.0.113.9".parse::<IpAddr>().unwrap());
        let other = cfg(&["--trusted-proxies", "10.0.0.0/8,::1"]);
        assert_eq!(url(&other, "127.0.0.1:5000", SPOOF), "http://vtex.internal:8080");
        assert_eq!(url(&other, "[::2]:5000", SPOOF), "http://vtex.internal:8080");
        assert_eq!(client_addr(&other, &request("127.0.0.1:5000", SPOOF)), IpAddr::from([127, 0, 0, 1]));
    }

    #[test]
    fn forwarded_headers_from_a_trusted_peer_are_honoured() {
        let c = cfg(&["--trusted-proxies", "127.0.0.1, 10.0.0.0/8"]);
        // `Forwarded` first: its host brings its own port; the prefix comes from X-Forwarded-Prefix.
        assert_eq!(url(&c, "10.1.2.3:5000", SPOOF), "https://evil.example/evil");
        assert_eq!(client_addr(&c, &request("10.1.2.3:5000", SPOOF)), IpAddr::from([192, 0, 2, 1]));
        let x = [
            ("host", "127.0.0.1:9000"),
            ("x-forwarded-host", "example.org"),
            ("x-forwarded-proto", "https"),
            ("x-forwarded-port", "8443"),
            ("x-forwarded-prefix", "/vtex/"),
            ("x-forwarded-for", "198.51.100.7"),
        ];
        assert_eq!(url(&c, "127.0.0.1:5000", &x), "https://example.org:8443/vtex");
        assert_eq!(client_addr(&c, &request("127.0.0.1:5000", &x)), IpAddr::from([198, 51, 100, 7]));
        // The default port of the scheme is left out; a Host-only proxy keeps the Host.
        let default = [("host", "example.org:443"), ("x-forwarded-proto", "HTTPS")];
        assert_eq!(url(&c, "127.0.0.1:1", &default), "https://example.org");
        assert_eq!(url(&c, "127.0.0.1:1", &[("host", "example.org:8080")]), "http://example.org:8080");
        assert_eq!(client_addr(&c, &request("127.0.0.1:1", &[])), IpAddr::from([127, 0, 0, 1]), "no header: the proxy");
    }

    #[test]
    fn a_chain_of_proxies_is_walked_back_to_the_first_untrusted_address() {
        let c = cfg(&["--trusted-proxies", "10.0.0.0/8"]);
        let fwd = [(
            "forwarded",
            "for=198.51.100.1;host=spoofed.example, for=192.0.2.60;proto=https;host=example.org, \
             for=10.0.0.7;host=inner:81",
        )];
        assert_eq!(url(&c, "10.0.0.8:1", &fwd), "https://example.org");
        assert_eq!(client_addr(&c, &request("10.0.0.8:1", &fwd)), IpAddr::from([192, 0, 2, 60]));
        let xff = [("x-forwarded-for", "198.51.100.1, 192.0.2.60"), ("x-forwarded-for", "10.0.0.7")];
        assert_eq!(client_addr(&c, &request("10.0.0.8:1", &xff)), IpAddr::from([192, 0, 2, 60]));
        // Only trusted proxies in the chain: the oldest entry is the client.
        assert_eq!(
            client_addr(&c, &request("10.0.0.8:1", &[("x-forwarded-for", "10.0.0.9")])),
            IpAddr::from([10, 0, 0, 9])
        );
        let unknown = [("forwarded", "for=unknown;host=example.org, for=\"_hidden\"")];
        assert_eq!(client_addr(&c, &request("10.0.0.8:1", &unknown)), UNKNOWN, "an unknown client is never the proxy");
    }

    #[test]
    fn malformed_forwarded_headers_are_ignored() {
        let c = cfg(&["--trusted-proxies", "127.0.0.1"]);
        let host = ("host", "vtex.internal:8080");
        for bad in [
            "for=192.0.2.1;host=evil.example;proto=https;host=twice.example",
            "for=192.0.2.1;host=\"evil.example",
            "for=192.0.2.1;host=evil.example;proto",
            "for=192.0.2.1 host=evil.example",
            "for=not-an-address;host=evil.example",
            "for=192.0.2.1;host=\"user@evil.example\"",
            "=x;host=evil.example",
            "for=192.0.2.1;host=\"evil.example\"junk",
            "for=192.0.2.1;host=evil.example/path",
        ] {
            assert_eq!(url(&c, "127.0.0.1:1", &[host, ("forwarded", bad)]), "http://vtex.internal:8080", "{bad}");
            let parts = request("127.0.0.1:1", &[host, ("forwarded", bad), ("x-forwarded-for", "192.0.2.9")]);
            assert_eq!(client_addr(&c, &parts), IpAddr::from([192, 0, 2, 9]), "{bad}: X-Forwarded-For instead");
        }
        // Valid forms: quoted strings with escapes, empty list elements, spaces, any case.
        let good = ", For=\"192.0.2.43\" ; HOST=\"exa\\mple.org\";proto=https ,,";
        assert_eq!(url(&c, "127.0.0.1:1", &[host, ("forwarded", good)]), "https://example.org");
        for (name, bad) in [
            ("x-forwarded-host", "evil.example/x"),
            ("x-forwarded-proto", "gopher"),
            ("x-forwarded-port", "99999"),
            ("x-forwarded-prefix", "/a/../b"),
            ("x-forwarded-prefix", "relative"),
            ("x-forwarded-prefix", "/a b"),
        ] {
            assert_eq!(url(&c, "127.0.0.1:1", &[host, (name, bad)]), "http://vtex.internal:8080", "{name}: {bad}");
        }
        assert_eq!(
            client_addr(&c, &request("127.0.0.1:1", &[("x-forwarded-for", "1.2.3.4, junk")])),
            IpAddr::from([127, 0, 0, 1])
        );
    }

    #[test]
    fn ipv6_peers_hosts_and_nodes() {
        let c = cfg(&["--trusted-proxies", "2001:db8::/32,::1"]);
        let fwd = [
            ("host", "[::1]:8080"),
            ("forwarded", "for=\"[2001:db9::5]:4711\";host=\"[2001:db8::10]:8443\";proto=https"),
        ];
        assert_eq!(url(&c, "[2001:db8::1]:5000", &fwd), "https://[2001:db8::10]:8443");
        assert_eq!(client_addr(&c, &request("[2001:db8::1]:5000", &fwd)), "2001:db9::5".parse::<IpAddr>().unwrap());
        assert_eq!(url(&c, "[2001:db9::1]:5000", &fwd), "http://[::1]:8080", "outside the range: not trusted");
        let xff = [("host", "[::1]:8080"), ("x-forwarded-for", "2001:db9::7, [2001:db8::2]:1")];
        assert_eq!(client_addr(&c, &request("[::1]:1", &xff)), "2001:db9::7".parse::<IpAddr>().unwrap());
        // An IPv4 client on a dual-stack socket arrives IPv4-mapped: trusted as its IPv4 address.
        let v4 = cfg(&["--trusted-proxies", "127.0.0.1"]);
        assert_eq!(url(&v4, "[::ffff:127.0.0.1]:1", &[("host", "a"), ("x-forwarded-host", "b")]), "http://b");
    }

    #[test]
    fn the_public_url_wins_and_is_validated() {
        let c = cfg(&["--public-url", "https://Example.org:443/vtex/", "--trusted-proxies", "0.0.0.0/0"]);
        assert_eq!(url(&c, "127.0.0.1:1", SPOOF), "https://example.org/vtex");
        assert_eq!(origin(&c, &request("127.0.0.1:1", &[])).url("/iiif/3/a"), "https://example.org/vtex/iiif/3/a");
        assert_eq!("http://[::1]:8080".parse::<PublicUrl>().unwrap(), PublicUrl("http://[::1]:8080".into()));
        for bad in [
            "example.org/vtex",
            "ftp://example.org/",
            "https://u:p@example.org/",
            "https://example.org/?a",
            "https://example.org/#x",
            "http://",
        ] {
            let e = bad.parse::<PublicUrl>().unwrap_err();
            assert!(e.contains(bad) && e.contains("https://example.org/vtex/"), "{e}");
        }
        for bad in ["10.0.0.0/33", "localhost", "1.2.3"] {
            assert!(bad.parse::<TrustedProxy>().unwrap_err().contains(bad));
        }
        // At start-up, clap's error names the option, the value and what is wrong.
        let e = Serve::try_parse_from(["vtex", "--public-url", "ftp://example.org/"]).err().unwrap().to_string();
        assert!(e.contains("--public-url") && e.contains("ftp://example.org/") && e.contains("http or https"), "{e}");
        let e =
            Serve::try_parse_from(["vtex", "--trusted-proxies", "127.0.0.1,10.0.0.0/33"]).err().unwrap().to_string();
        assert!(e.contains("--trusted-proxies") && e.contains("10.0.0.0/33"), "{e}");
    }

    #[test]
    fn without_anything_the_host_alone() {
        let c = cfg(&[]);
        assert_eq!(url(&c, "127.0.0.1:1", &[("host", "127.0.0.1:8080")]), "http://127.0.0.1:8080");
        let parts = Request::get("/").body(()).unwrap().into_parts().0;
        assert_eq!(origin(&c, &parts).to_string(), "http://localhost");
        assert_eq!(client_addr(&c, &parts), UNKNOWN, "no connection: unknown");
    }
}
