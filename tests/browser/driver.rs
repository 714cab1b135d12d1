//! The two browsers the gallery is tested in, their WebDriver servers (chromedriver,
//! geckodriver) and the headless sessions these start.

use std::net::{TcpListener, TcpStream};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use fantoccini::{Client, ClientBuilder};
use serde_json::{Map, Value, json};

/// The window every session starts with (the outer window, as WebDriver sizes it).
pub const WINDOW: (u32, u32) = (1280, 800);

/// A browser the tests run in, with its WebDriver server.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Browser {
    /// Debian's `chromium` through `chromedriver` (package `chromium-driver`).
    Chromium,
    /// Debian's `firefox-esr` through `geckodriver` (crates.io: Debian has no package).
    Firefox,
}

impl Browser {
    pub fn name(self) -> &'static str {
        match self {
            Browser::Chromium => "Chromium",
            Browser::Firefox => "Firefox",
        }
    }

    /// How to install what this browser's tests need.
    fn install_hint(self) -> &'static str {
        match self {
            Browser::Chromium => "`apt-get install -y chromium chromium-driver`",
            Browser::Firefox => {
                "`apt-get install -y firefox-esr` and `cargo install geckodriver --locked` \
                 (Debian has no geckodriver package; it goes to ~/.cargo/bin, which must be on PATH)"
            }
        }
    }

    /// The WebDriver server: `$CHROMEDRIVER` / `$GECKODRIVER`, else found on PATH.
    fn webdriver(self) -> PathBuf {
        match self {
            Browser::Chromium => self.find("CHROMEDRIVER", &["chromedriver"]),
            Browser::Firefox => self.find("GECKODRIVER", &["geckodriver"]),
        }
    }

    /// The browser itself: `$CHROMIUM` / `$FIREFOX`, else found on PATH.
    fn binary(self) -> PathBuf {
        match self {
            Browser::Chromium => self.find("CHROMIUM", &["chromium", "chromium-browser"]),
            Browser::Firefox => self.find("FIREFOX", &["firefox-esr", "firefox"]),
        }
    }

    /// The WebDriver server's arguments to listen on `port`; geckodriver's WebDriver BiDi
    /// port is left to the system too, or two geckodrivers would both want 9222.
    fn webdriver_args(self, port: u16) -> Vec<String> {
        match self {
            Browser::Chromium => vec![format!("--port={port}")],
            Browser::Firefox => ["--port", &port.to_string(), "--websocket-port", "0"]
                .map(String::from)
                .to_vec(),
        }
    }

    /// The capabilities of a headless session with a `WINDOW`-sized window. Firefox gets a
    /// fresh profile in `profile` (made here) whose browser chrome may be narrower than its
    /// usual 500 px minimum, so that its window takes a phone's width as Chromium's does.
    fn capabilities(self, profile: &Path) -> Map<String, Value> {
        let (w, h) = WINDOW;
        let caps = match self {
            Browser::Chromium => json!({
                "browserName": "chrome",
                "goog:chromeOptions": {
                    "binary": self.binary(),
                    "args": ["--headless=new", "--no-sandbox", "--disable-gpu",
                             "--disable-dev-shm-usage", format!("--window-size={w},{h}"),
                             "--hide-scrollbars", "--force-device-scale-factor=1"],
                },
            }),
            Browser::Firefox => {
                let chrome = profile.join("chrome");
                std::fs::create_dir_all(&chrome).unwrap();
                std::fs::write(
                    chrome.join("userChrome.css"),
                    ":root { --window-min-width: 0px !important; }\n",
                )
                .unwrap();
                json!({
                    "browserName": "firefox",
                    "moz:firefoxOptions": {
                        "binary": self.binary(),
                        "args": ["-headless", format!("--width={w}"), format!("--height={h}"),
                                 "-profile", profile],
                        "prefs": {"toolkit.legacyUserProfileCustomizations.stylesheets": true},
                    },
                })
            }
        };
        match caps {
            Value::Object(m) => m,
            _ => unreachable!(),
        }
    }

    /// A program named by the environment variable `var`, else on PATH, or a clear failure.
    fn find(self, var: &str, names: &[&str]) -> PathBuf {
        let candidates: Vec<PathBuf> = match std::env::var_os(var) {
            Some(p) => vec![PathBuf::from(p)],
            None => std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default())
                .flat_map(|dir| names.iter().map(move |n| dir.join(n)))
                .collect(),
        };
        if let Some(p) = candidates.into_iter().find(|p| p.is_file()) {
            return p;
        }
        panic!(
            "{} not found (looked at ${var} if set, else on PATH): the browser tests in {} need {}; \
             .ci/run installs them",
            names.join(" / "),
            self.name(),
            self.install_hint()
        );
    }
}

/// A browser's WebDriver server on a free port, in a process group of its own so that
/// dropping it also ends the browser processes it started. Their temporary files (`$TMPDIR`)
/// and Firefox's profiles go in a folder of its own, removed then too.
pub struct Driver {
    browser: Browser,
    child: Child,
    url: String,
    /// `$TMPDIR` of the processes and Firefox's profiles (one a session); dropped (removed)
    /// after `drop` has ended the processes.
    tmp: tempfile::TempDir,
    sessions: AtomicUsize,
}

impl Driver {
    pub fn start(browser: Browser) -> Driver {
        let program = browser.webdriver();
        let tmp = tempfile::tempdir().unwrap();
        let port = TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let child = Command::new(&program)
            .args(browser.webdriver_args(port))
            .env("TMPDIR", tmp.path())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .process_group(0)
            .spawn()
            .unwrap_or_else(|e| panic!("start {}: {e}", program.display()));
        let t0 = Instant::now();
        while TcpStream::connect(("127.0.0.1", port)).is_err() {
            assert!(
                t0.elapsed() < Duration::from_secs(20),
                "{} did not listen on port {port} within 20 s",
                program.display()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        Driver {
            browser,
            child,
            url: format!("http://127.0.0.1:{port}"),
            tmp,
            sessions: AtomicUsize::new(0),
        }
    }

    /// A new headless session; its window is `WINDOW`. geckodriver serves one session at a
    /// time, so two browsers open at once need a `Driver` each.
    pub async fn session(&self) -> Client {
        let name = self.browser.name();
        let n = self.sessions.fetch_add(1, Ordering::Relaxed);
        let profile = self.tmp.path().join(format!("profile-{n}"));
        let c = ClientBuilder::new(hyper_util::client::legacy::connect::HttpConnector::new())
            .capabilities(self.browser.capabilities(&profile))
            .connect(&self.url)
            .await
            .unwrap_or_else(|e| panic!("start a {name} session through its WebDriver: {e}"));
        let (w, h) = WINDOW;
        if c.get_window_size().await.unwrap() != (u64::from(w), u64::from(h)) {
            c.set_window_size(w, h).await.unwrap();
        }
        assert_eq!(
            c.get_window_size().await.unwrap(),
            (u64::from(w), u64::from(h)),
            "{name}'s window"
        );
        c
    }
}

impl Drop for Driver {
    fn drop(&mut self) {
        // SAFETY: signalling the process group of a child we started.
        unsafe {
            libc::kill(-(self.child.id() as i32), libc::SIGKILL);
        }
        let _ = self.child.wait();
    }
}
