//! `vtex health`: asks a running `vtex serve` whether it is ready (`GET /readyz`) and exits
//! non-zero when it is not, so a container's health check needs nothing but the binary.

use anyhow::{bail, Context};
use clap::Args;
use http_body_util::{BodyExt, Empty};
use hyper::body::Bytes;
use hyper_util::rt::TokioIo;
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr};
use std::time::Duration;

#[derive(Args, Debug)]
pub struct HealthArgs {
    /// The address `vtex serve` listens on (its `--bind`); one bound to every interface
    /// (0.0.0.0, [::]) is asked on loopback.
    #[arg(long, env = "VTEX_BIND", default_value = "127.0.0.1:8080")]
    pub bind: SocketAddr,
    /// Seconds to wait for the answer.
    #[arg(long, default_value_t = 3)]
    pub timeout: u64,
}

/// Prints the readiness answer; an error (exit status 1) unless it is 200.
pub fn health(args: HealthArgs) -> anyhow::Result<()> {
    let mut addr = args.bind;
    if addr.ip().is_unspecified() {
        addr.set_ip(if addr.is_ipv4() { IpAddr::V4(Ipv4Addr::LOCALHOST) } else { IpAddr::V6(Ipv6Addr::LOCALHOST) });
    }
    let url = format!("http://{addr}/readyz");
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
    let (status, body) = rt
        .block_on(async { tokio::time::timeout(Duration::from_secs(args.timeout), get(addr)).await })
        .map_err(|_| anyhow::anyhow!("no answer within {} s", args.timeout))
        .and_then(|answer| answer)
        .with_context(|| format!("GET {url}"))?;
    let body = String::from_utf8_lossy(&body);
    if status != hyper::StatusCode::OK {
        bail!("GET {url}: {status} {}", body.trim());
    }
    println!("{}", body.trim());
    Ok(())
}

async fn get(addr: SocketAddr) -> anyhow::Result<(hyper::StatusCode, Bytes)> {
    let stream = tokio::net::TcpStream::connect(addr).await?;
    let (mut sender, conn) = hyper::client::conn::http1::handshake(TokioIo::new(stream)).await?;
    tokio::spawn(conn);
    let request =
        hyper::Request::get("/readyz").header(hyper::header::HOST, addr.to_string()).body(Empty::<Bytes>::new())?;
    let response = sender.send_request(request).await?;
    let status = response.status();
    Ok((status, response.into_body().collect().await?.to_bytes()))
}
