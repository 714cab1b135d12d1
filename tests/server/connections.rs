//! What a hostile or careless client tried at the connection level (docs/security.md), each
//! held by a test here: bodies refused before they are read, idle, slow and non-reading
//! connections closed, a connection cap below the descriptor limit, bounded metric labels.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

use serde_json::json;

use super::harness::*;

/// Send `head` (request line and headers, no body) on a new connection and read what the
/// server answers first, up to the end of its head. The read timeout only bounds a failure:
/// a server that waits for the body never answers.
fn first_response_head(s: &Server, head: &str) -> String {
    let mut c = TcpStream::connect(s.addr()).unwrap();
    c.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    c.write_all(head.as_bytes()).unwrap();
    let mut got = Vec::new();
    let mut buf = [0u8; 4096];
    while !got.windows(4).any(|w| w == b"\r\n\r\n") {
        match c.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => got.extend_from_slice(&buf[..n]),
            Err(e) => panic!("no answer before the body was sent ({e}); got {got:?}"),
        }
    }
    String::from_utf8_lossy(&got).into_owned()
}

#[test]
fn bodies_are_refused_before_they_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    let post = |extra: &str| {
        format!(
            "POST /api/jobs HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n\
             Content-Length: 16000000\r\n{extra}\r\n"
        )
    };
    // No token: 401 with the 16 MB body never sent.
    let head = first_response_head(&s, &post(""));
    assert!(head.starts_with("HTTP/1.1 401"), "{head}");
    // Expect: 100-continue without a token: 401, and no `100 Continue` first.
    let head = first_response_head(&s, &post("Expect: 100-continue\r\n"));
    assert!(head.starts_with("HTTP/1.1 401"), "{head}");
    // A token, but a declared body over the limit (16 MiB default is above 16000000: use a
    // bigger one): 413 before the body, with or without Expect.
    let big = |extra: &str| {
        format!(
            "POST /api/jobs HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {}\r\n\
             Content-Length: 100000000\r\n{extra}\r\n",
            s.admin
        )
    };
    let head = first_response_head(&s, &big(""));
    assert!(head.starts_with("HTTP/1.1 413"), "{head}");
    let head = first_response_head(&s, &big("Expect: 100-continue\r\n"));
    assert!(head.starts_with("HTTP/1.1 413"), "{head}");
    // A good token and a small body still get their `100 Continue` and the job.
    let body =
        json!({"scene_name": "cornell", "params": {"integrator": "photon", "width": 8, "height": 8,
        "photons": 1000, "caustic_photons": 0, "spp": 1, "gather_rays": 0}})
        .to_string();
    let mut c = TcpStream::connect(s.addr()).unwrap();
    c.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    write!(
        c,
        "POST /api/jobs HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {}\r\n\
         Content-Type: application/json\r\nContent-Length: {}\r\nExpect: 100-continue\r\n\r\n",
        s.admin,
        body.len()
    )
    .unwrap();
    let mut buf = [0u8; 256];
    let n = c.read(&mut buf).unwrap();
    let cont = String::from_utf8_lossy(&buf[..n]).into_owned();
    assert!(cont.starts_with("HTTP/1.1 100"), "{cont}");
    c.write_all(body.as_bytes()).unwrap();
    let mut rest = String::new();
    let _ = c.read_to_string(&mut rest);
    assert!(rest.contains("202 Accepted"), "{rest}");
}

/// Raise this process's soft descriptor limit to its hard one (the test holds more
/// connections than the server may).
fn raise_own_nofile() -> u64 {
    let mut lim = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: get/setrlimit on our own process with a valid struct.
    unsafe {
        libc::getrlimit(libc::RLIMIT_NOFILE, &mut lim);
        lim.rlim_cur = lim.rlim_max;
        libc::setrlimit(libc::RLIMIT_NOFILE, &lim);
    }
    lim.rlim_cur
}

#[test]
fn idle_and_slow_connections_are_closed_and_the_server_answers_past_its_descriptor_limit() {
    let held = 1200;
    assert!(
        raise_own_nofile() > held as u64 + 100,
        "the test needs descriptors"
    );
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start_limited(dir.path(), &["--header-timeout", "1"], Some(1024));
    // More idle connections than the server has descriptors.
    let idle: Vec<TcpStream> = (0..held)
        .map(|_| TcpStream::connect(s.addr()).unwrap())
        .collect();
    // A slow sender: a header byte at a time, never a complete head.
    let mut slow = TcpStream::connect(s.addr()).unwrap();
    slow.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\nX-Slow: ")
        .unwrap();
    // The server goes on answering everyone (once the idle ones time out, the cap frees).
    let r = client().get(s.url("/healthz")).send().unwrap();
    assert_eq!(r.status().as_u16(), 200);
    assert_eq!(r.text().unwrap(), "ok\n");
    // Every idle connection is closed by the server (EOF), and so is the slow sender.
    let closed = |mut c: TcpStream| {
        c.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
        let mut b = [0u8; 512];
        loop {
            match c.read(&mut b) {
                Ok(0) => return true,
                Ok(_) => continue, // a 408 before closing is fine
                Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => return true,
                Err(_) => return false,
            }
        }
    };
    let open = idle
        .into_iter()
        .filter(|_| true)
        .map(closed)
        .filter(|c| !c)
        .count();
    assert_eq!(open, 0, "idle connections left open by the server");
    for _ in 0..3 {
        if slow.write_all(b"a").is_err() {
            break;
        }
    }
    assert!(closed(slow), "the slow sender was not closed");
    // And the server still serves after all that.
    let (status, me) = get(&s, &s.admin, "/api/me");
    assert_eq!(status, 200, "{me}");
}

#[test]
fn metric_labels_stay_bounded_whatever_the_methods_and_paths() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    for i in 0..200 {
        let mut c = TcpStream::connect(s.addr()).unwrap();
        c.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
        write!(
            c,
            "M{i}XYZ /no/such/path/{i} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n"
        )
        .unwrap();
        let mut out = String::new();
        let _ = c.read_to_string(&mut out);
        assert!(out.starts_with("HTTP/1.1 4"), "{out}");
    }
    let text = metrics(&s);
    assert!(!text.contains("XYZ"), "a client's method became a label");
    assert!(!text.contains("/no/such"), "a client's path became a label");
    let http: Vec<&str> = text
        .lines()
        .filter(|l| l.starts_with("photonbox_http_requests_total{"))
        .collect();
    assert!(
        http.iter().any(|l| l.contains("method=\"other\"")),
        "{http:?}"
    );
    assert!(http.len() <= 4, "labels grew with the requests: {http:?}");
}

#[test]
fn clients_that_stop_reading_do_not_keep_their_connections() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(
        dir.path(),
        &[
            "--max-connections",
            "4",
            "--write-timeout",
            "1",
            "--header-timeout",
            "600",
        ],
    );
    // A 30 MB download, more than the socket buffers of both ends hold (the client's receive
    // buffer is pinned small: Linux would otherwise grow it to tens of MB).
    let id = run_to_done(
        &s,
        &s.admin,
        json!({"scene_name": "cornell", "params": {"integrator": "raytrace",
               "width": 2048, "height": 2048, "spp": 1}}),
    );
    // Every permitted connection asks for it and reads none of it.
    let request = format!(
        "GET /api/jobs/{id}/image.exr HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {}\r\n\r\n",
        s.admin
    );
    let stalled: Vec<TcpStream> = (0..4)
        .map(|_| {
            let mut c = TcpStream::connect(s.addr()).unwrap();
            small_receive_buffer(&c);
            c.write_all(request.as_bytes()).unwrap();
            c
        })
        .collect();
    // Someone else is still served: the stalled writes time out and free the cap (without
    // the write timeout, the four would hold it for as long as they like).
    let quick = reqwest::blocking::Client::builder()
        .timeout(Duration::from_secs(60))
        .build()
        .unwrap();
    let r = quick.get(s.url("/healthz")).send().unwrap();
    assert_eq!(r.status().as_u16(), 200);
    drop(stalled);
}

/// Pin a socket's receive buffer at 64 KiB (no autotuning).
fn small_receive_buffer(c: &TcpStream) {
    use std::os::fd::AsRawFd;
    let size: libc::c_int = 64 << 10;
    // SAFETY: setsockopt on an open socket with a valid int option.
    let r = unsafe {
        libc::setsockopt(
            c.as_raw_fd(),
            libc::SOL_SOCKET,
            libc::SO_RCVBUF,
            (&size as *const libc::c_int).cast(),
            std::mem::size_of::<libc::c_int>() as libc::socklen_t,
        )
    };
    assert_eq!(r, 0, "setsockopt SO_RCVBUF");
}
