//! `tutti studio` driven through a real headless Chromium (Debian's `chromium` and
//! `chromium-driver`, over WebDriver with fantoccini). Each test runs the real `tutti`
//! binary on a free port with its own root folder, namespace, chromedriver port and Chromium
//! profile; every process is killed and every folder removed even when the test fails.
//! Without Chromium the tests are skipped with a message, except under `CI=true`, where
//! that is a failure. With `TUTTI_SCREENSHOTS=1` they write their screenshots to
//! `docs/img/`.

use tutti_test_support as common;

use std::future::Future;
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use fantoccini::{Client, ClientBuilder, Locator};
use serde_json::{json, Value};
use tutti_test_support::{Proc, Spawn};

/// Longest wait for anything the page should show.
const WAIT: Duration = Duration::from_secs(30);
/// Longest a whole test may take.
const TEST_LIMIT: Duration = Duration::from_secs(240);

fn repo() -> &'static Path {
    common::repo_root()
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0").and_then(|l| l.local_addr()).map(|a| a.port()).expect("a free port")
}

/// A child process in its own process group, killed with its whole group when dropped
/// (chromedriver starts the browser, which starts processes of its own).
fn spawn(name: &str, cmd: Command, output: bool) -> Proc {
    let opts = Spawn {
        watchdog: TEST_LIMIT + WAIT,
        stdout: output,
        stderr: output,
        process_group: true,
        grace: Duration::ZERO,
    };
    Proc::spawn_with(name, cmd, opts)
}

/// One test's world: a root folder, a studio, a chromedriver and a browser session.
struct World {
    client: Option<Client>,
    root: PathBuf,
    namespace: String,
    // Dropped in this order: the browser's driver first, then the studio, then the folders.
    _driver: Proc,
    _studio: Proc,
    _profile: tempfile::TempDir,
    _dir: tempfile::TempDir,
}

/// Chromium and chromedriver, or None (skipped; a failure under CI=true).
fn browser() -> Option<(PathBuf, PathBuf)> {
    Some((common::require_tool("chromium", "chromium")?, common::require_tool("chromedriver", "chromium-driver")?))
}

impl World {
    /// Starts a studio on `files` (copied from ddf/ into a fresh root) and a browser on it.
    async fn start(test: &str, files: &[&str], extra: &[(&str, &str)]) -> Option<World> {
        let (chromium, chromedriver) = browser()?;
        let dir = tempfile::tempdir().expect("temp dir");
        let root = dir.path().join("root");
        std::fs::create_dir(&root).expect("root");
        for f in files {
            std::fs::copy(repo().join("ddf").join(f), root.join(f)).expect("copy DDF");
        }
        for (name, text) in extra {
            std::fs::write(root.join(name), text).expect("write file");
        }
        let namespace = tutti_test_support::namespace(&format!("studio-{test}-"));
        let mut cmd = common::tutti_command();
        cmd.args(["studio", "--listen", "127.0.0.1:0", "--root"])
            .arg(&root)
            .args(files.iter().chain(extra.iter().map(|(n, _)| n)).take(1))
            .env("TUTTI_NAMESPACE", &namespace);
        let studio = spawn("tutti studio", cmd, true);
        let url = listening_url(&studio);

        let port = free_port();
        let mut cmd = Command::new(chromedriver);
        cmd.arg(format!("--port={port}")).stdout(Stdio::null()).stderr(Stdio::null());
        let driver = spawn("chromedriver", cmd, false);
        let profile = tempfile::tempdir().expect("profile dir");
        let caps = json!({
            "browserName": "chrome",
            "goog:chromeOptions": {
                "binary": chromium,
                "args": ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                         "--window-size=1400,1000", format!("--user-data-dir={}", profile.path().display())],
            }
        });
        let Value::Object(caps) = caps else { unreachable!() };
        let webdriver = format!("http://127.0.0.1:{port}");
        let (caps, at) = (&caps, webdriver.as_str());
        let client = retry(
            Duration::from_millis(200),
            |_| true,
            || async move {
                let connector = hyper_util::client::legacy::connect::HttpConnector::new();
                ClientBuilder::new(connector).capabilities(caps.clone()).connect(at).await
            },
        )
        .await
        .unwrap_or_else(|e| panic!("no WebDriver session on {webdriver}: {e}"));
        client.goto(&url).await.expect("open the studio");
        Some(World {
            client: Some(client),
            root,
            namespace,
            _driver: driver,
            _studio: studio,
            _profile: profile,
            _dir: dir,
        })
    }

    fn c(&self) -> &Client {
        self.client.as_ref().expect("browser session")
    }

    /// Ends the browser session (the drivers are killed on drop either way).
    async fn close(mut self) {
        if let Some(c) = self.client.take() {
            let _ = c.close().await;
        }
    }

    async fn find(&self, css: &str) -> fantoccini::elements::Element {
        self.c().wait().at_most(WAIT).for_element(Locator::Css(css)).await.unwrap_or_else(|e| panic!("{css}: {e}"))
    }

    /// Clicks the element `css` finds. The page re-renders parts of itself when an answer of
    /// the server arrives (validation, layout), which can replace the element between finding
    /// and clicking it: a stale element is found again (within the wait), never clicked blind.
    async fn click(&self, css: &str) {
        retry(Duration::ZERO, is_stale, || async move { self.find(css).await.click().await })
            .await
            .unwrap_or_else(|e| panic!("click {css}: {e}"));
    }

    /// Clears the field `css` finds and types `text` into it (found again if re-rendered).
    async fn type_into(&self, css: &str, text: &str) {
        retry(Duration::ZERO, is_stale, || async move {
            let e = self.find(css).await;
            match e.clear().await {
                Ok(()) => e.send_keys(text).await,
                Err(err) => Err(err),
            }
        })
        .await
        .unwrap_or_else(|err| panic!("type into {css}: {err}"));
    }

    /// Waits until `script` (a JS expression) is truthy; returns its value.
    async fn until(&self, what: &str, script: &str) -> Value {
        let truthy = retry(
            Duration::from_millis(100),
            |_| true,
            || async move {
                let v = self.c().execute(&format!("return ({script});"), vec![]).await.unwrap_or(Value::Null);
                let truthy = match &v {
                    Value::Null => false,
                    Value::Bool(b) => *b,
                    Value::String(s) => !s.is_empty(),
                    Value::Number(n) => n.as_f64() != Some(0.0),
                    _ => true,
                };
                if truthy {
                    Ok(v)
                } else {
                    Err(())
                }
            },
        )
        .await;
        match truthy {
            Ok(v) => v,
            Err(()) => {
                let msg = self.text("#message").await;
                panic!("waited {WAIT:?} for {what} ({script}); page message: {msg}");
            }
        }
    }

    async fn text(&self, css: &str) -> String {
        let script = format!("var e = document.querySelector({css:?}); return e ? e.textContent : '';");
        self.c().execute(&script, vec![]).await.ok().and_then(|v| v.as_str().map(str::to_string)).unwrap_or_default()
    }

    async fn message_contains(&self, text: &str) -> String {
        let script = format!("document.getElementById('message').textContent.includes({text:?})");
        self.until(&format!("the message '{text}'"), &script).await;
        self.text("#message").await
    }

    /// Writes a screenshot to docs/img/NAME when TUTTI_SCREENSHOTS=1.
    async fn screenshot(&self, name: &str) {
        if std::env::var("TUTTI_SCREENSHOTS").as_deref() != Ok("1") {
            return;
        }
        let png = self.c().screenshot().await.expect("screenshot");
        let dir = repo().join("docs/img");
        std::fs::create_dir_all(&dir).expect("docs/img");
        std::fs::write(dir.join(name), png).expect("write screenshot");
    }
}

/// Waits until the studio says where it listens.
fn listening_url(studio: &Proc) -> String {
    let prefix = "stderr: tutti studio: listening on ";
    let line = studio.wait_line(prefix, WAIT);
    let line = line.unwrap_or_else(|| panic!("the studio did not say where it listens\n{}", studio.dump()));
    line[prefix.len()..].to_string()
}

async fn with_limit(f: impl std::future::Future<Output = ()>) {
    tokio::time::timeout(TEST_LIMIT, f).await.expect("the test took too long");
}

/// Domains, flags, and per set the items' paths, types and lengths of `tutti show --json`.
fn shape(file: &Path) -> Value {
    let (code, out, err) = common::tutti(["show".as_ref(), "--json".as_ref(), file.as_os_str()]);
    assert_eq!(code, 0, "tutti show {}: {err}", file.display());
    let v: Value = serde_json::from_str(&out).expect("show JSON");
    let domains = v["domains"].as_array().expect("domains").iter().map(|d| {
        let sets: Vec<Value> = d["sets"]
            .as_array()
            .expect("sets")
            .iter()
            .map(|s| {
                let items: Vec<Value> = s["items"]
                    .as_array()
                    .expect("items")
                    .iter()
                    .map(|i| json!([i["path"], i["type"], i["length"], i["offset"]]))
                    .collect();
                json!({ "role": s["role"], "items": items })
            })
            .collect();
        json!({ "name": d["name"], "synchronous": d["synchronous"],
                "multiple_publish_allowed": d["multiple_publish_allowed"], "states": d["states"], "sets": sets })
    });
    Value::Array(domains.collect())
}

/// (a) The paper's Figure 2 built from an empty file through the forms: a name with a space
/// is flagged at its field, fixed, saved; `tutti check` accepts the file and `tutti show`
/// sees what it sees in ddf/paper-figure2.ddf.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn build_figure2_from_an_empty_file() {
    with_limit(async {
        let Some(w) = World::start("fig2", &[], &[("fig2.ddf", "")]).await else { return };
        w.message_contains("opened fig2.ddf").await;
        w.click("#add-domain").await;
        w.type_into("[data-field='d0']", "multiuav uav1").await;
        w.until("the diagnostic at the domain's name", "document.querySelector(\"[data-diag-for='d0']\")").await;
        let at_field = w.text("[data-diag-for='d0']").await;
        assert!(at_field.contains("whitespace"), "{at_field}");
        assert!(w.text("#diags").await.contains("multiuav uav1"));
        // Clicking the diagnostic in the list goes to the field.
        w.click("#diags li[data-diag='d0']").await;
        w.until("the name field focused", "document.activeElement.dataset.field === 'd0'").await;
        w.click("#add-publish-0").await;
        w.click("#add-publish-0").await;
        for _ in 0..3 {
            w.click("#add-subscribe-0").await;
        }
        w.type_into("[data-field='d0.publish.i0']", "Autopilot").await;
        w.type_into("[data-field='d0.publish.i1']", "X").await;
        for (k, name) in ["Latitude", "Longitude", "Elevation"].iter().enumerate() {
            w.type_into(&format!("[data-field='d0.subscribe.i{k}']"), name).await;
        }
        w.until("the XML in step", "document.getElementById('xml').value.includes('Elevation')").await;
        w.until("the diagnostic still shown", "document.querySelector(\"[data-diag-for='d0']\")").await;
        w.screenshot("studio-editor-diagnostic.png").await;
        w.type_into("[data-field='d0']", "multiuav_uav1").await;
        w.until("the name accepted", "!document.querySelector(\"[data-diag-for='d0']\")").await;
        w.click("[data-field='d0.synchronous']").await;
        w.click("[data-field='d0.multiple_publish_allowed']").await;
        let flags = "[document.querySelector(\"[data-field='d0.synchronous']\").checked, \
                     document.querySelector(\"[data-field='d0.multiple_publish_allowed']\").checked]";
        assert_eq!(w.until("the flags", flags).await, json!([true, false]), "the flags' boxes after one click each");
        w.until("the flags in the XML", "document.getElementById('xml').value.includes('<multiplePublishAllowed>no')")
            .await;
        w.until("no problem left", "document.getElementById('diag-count').textContent === '(none)'").await;
        w.until(
            "the layout shown",
            "document.getElementById('layout').textContent.includes('rt/multiuav_uav1/subscribe')",
        )
        .await;
        w.screenshot("studio-editor.png").await;
        // Duplicate the domain, then delete the copy.
        w.click("[data-action='duplicate-domain']").await;
        w.until("the copy", "(document.querySelector(\"[data-field='d1']\") || {}).value === 'multiuav_uav1_copy'")
            .await;
        w.until("the copy in the XML", "document.getElementById('xml').value.includes('multiuav_uav1_copy')").await;
        w.click(".domain:nth-of-type(2) [data-action='delete-domain']").await;
        w.until("the copy gone", "!document.getElementById('xml').value.includes('multiuav_uav1_copy')").await;
        // The same from the tree.
        w.click("#tree [data-tree-domain='d0'] [data-action='duplicate-domain']").await;
        w.until("the copy in the tree", "document.getElementById('tree').textContent.includes('multiuav_uav1_copy')")
            .await;
        w.click("#tree [data-tree-domain='d1'] [data-action='delete-domain']").await;
        w.until("the copy gone again", "!document.getElementById('xml').value.includes('multiuav_uav1_copy')").await;
        w.click("#save").await;
        w.message_contains("saved fig2.ddf").await;
        let saved = w.root.join("fig2.ddf");
        let (code, _, err) = common::tutti(["check".as_ref(), saved.as_os_str()]);
        assert_eq!(code, 0, "tutti check of the saved file: {err}");
        assert_eq!(shape(&saved), shape(&repo().join("ddf/paper-figure2.ddf")));
        w.close().await;
    })
    .await;
}

/// (c) Saving over a file changed on disk since it was opened, and opening a file outside
/// the root: both refused with a message; the file on disk is untouched.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn refuses_a_changed_file_and_paths_outside_the_root() {
    with_limit(async {
        let Some(w) = World::start("refuse", &["paper-figure2.ddf"], &[]).await else { return };
        w.message_contains("opened paper-figure2.ddf").await;
        let file = w.root.join("paper-figure2.ddf");
        let changed = format!("{}<!-- changed by someone else -->\n", std::fs::read_to_string(&file).expect("read"));
        std::fs::write(&file, &changed).expect("change the file");
        w.type_into("[data-field='d0.publish.i1']", "Y").await;
        w.click("#save").await;
        let msg = w.message_contains("changed on disk").await;
        assert!(msg.contains("not saved"), "{msg}");
        w.until("the reload button", "!document.getElementById('reload').hidden").await;
        w.screenshot("studio-changed-on-disk.png").await;
        assert_eq!(std::fs::read_to_string(&file).expect("read"), changed);
        w.click("#reload").await;
        w.message_contains("opened paper-figure2.ddf").await;
        w.until("the file as on disk", "document.querySelector(\"[data-field='d0.publish.i1']\").value === 'X'").await;

        // An invalid file opens as XML with its problems; fixed there, it fills the forms.
        std::fs::write(w.root.join("bad.ddf"), "<orchestra>\n<domain name=\"a b\"/>\n</orchestra>\n").expect("bad.ddf");
        w.type_into("#path", "bad.ddf").await;
        w.click("#open").await;
        w.message_contains("not a valid DDF").await;
        assert!(w.text("#diags").await.contains("line 2"), "{}", w.text("#diags").await);
        let fixed = "<orchestra><domain name=\"ab\"><set name=\"PUBLISH\"><item name=\"x\"><type>double</type></item></set></domain></orchestra>";
        w.type_into("#xml", fixed).await;
        w.click("#apply-xml").await;
        w.message_contains("XML applied").await;
        w.until("the forms filled", "(document.querySelector(\"[data-field='d0']\") || {}).value === 'ab'").await;

        w.type_into("#path", "../../etc/passwd").await;
        w.click("#open").await;
        let msg = w.message_contains("outside the studio's root").await;
        assert!(msg.contains("refused"), "{msg}");
        assert!(!w.text("#form").await.contains("root:"), "the page shows nothing of the file");
        w.close().await;
    })
    .await;
}

/// Compiles tests/studio/ramp.c against the RTAPI into `dir`.
fn compile_ramp(dir: &Path) -> PathBuf {
    common::compile_c(
        &repo().join("tests/studio/ramp.c"),
        &dir.join("ramp"),
        &["-std=c99", "-Wall", "-Wextra", "-Werror"],
    )
}

/// (b) ddf/multiuav.ddf opened, its host started from the page, a C component connected:
/// its connection appears in the table and the item it writes changes in the plot; killed
/// with SIGKILL, its connection goes. Then run control: pause, step, resume, and a
/// checkpoint saved (its file appears in the root), restored, and a file that is not one
/// refused with the reason.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn monitor_follows_a_host_started_from_the_page_and_a_c_component() {
    with_limit(async {
        let Some(w) = World::start("monitor", &["multiuav.ddf"], &[]).await else { return };
        let ramp = compile_ramp(w.root.parent().expect("temp dir"));
        w.message_contains("opened multiuav.ddf").await;
        w.click("#tab-monitor").await;
        w.type_into("#run-step", "10ms").await;
        w.click("#start-host").await;
        w.message_contains("started tutti host").await;
        w.until(
            "the domain with its framework",
            "(document.querySelector(\"[data-domain='multiuav_uav1']\") || {textContent: ''}).textContent.includes('steps/s')",
        )
        .await;
        let key = "multiuav_uav1#SUBSCRIBE#Elevation";
        w.until("the item in the plot menu", &format!("document.querySelector(\"#plot-item option[value='{key}']\")")).await;
        // The menu is rebuilt as the monitor's events arrive: select in the current one.
        let world = &w;
        retry(Duration::ZERO, is_stale, || async move { world.find("#plot-item").await.select_by_value(key).await })
            .await
            .unwrap_or_else(|e| panic!("select the item: {e}"));
        w.click("#plot-add").await;
        w.until("the item plotted", &format!("document.querySelector(\"[data-series='{key}']\")")).await;

        let mut cmd = Command::new(&ramp);
        cmd.args(["multiuav_uav1", "Elevation"])
            .env("TUTTI_NAMESPACE", &w.namespace)
            .stdout(Stdio::null());
        let component = spawn("ramp", cmd, false);
        let pid = component.id();
        w.until("the component's connection", &format!("document.querySelector(\"#domains tr[data-pid='{pid}']\")")).await;
        let value = format!("+document.querySelector(\"[data-series='{key}']\").dataset.value");
        let first = w.until("the plotted value moving", &format!("{value} > 1 ? {value} : 0")).await;
        let first = first.as_f64().expect("a number");
        w.until("the plotted value changing", &format!("{value} > {first}")).await;
        if std::env::var("TUTTI_SCREENSHOTS").as_deref() == Ok("1") {
            // A few seconds of the ramp in the picture.
            w.until("a longer ramp", &format!("{value} > {first} + 150")).await;
        }
        w.screenshot("studio-monitor.png").await;

        Command::new("kill").args(["-KILL", &pid.to_string()]).status().expect("kill -9");
        w.until("the connection gone", &format!("!document.querySelector(\"#domains tr[data-pid='{pid}']\")")).await;
        drop(component);

        // Run control through the framework's control plane: pause, step 3, resume.
        w.click("#pause-host").await;
        let state = "document.querySelector('#run-state').dataset";
        let paused = w.until("the run paused", &format!("{state}.state === 'paused' && +{state}.step")).await;
        let at = paused.as_u64().expect("the step where it paused");
        w.type_into("#step-count", "3").await;
        w.click("#step-host").await;
        w.until("three steps made", &format!("{state}.state === 'paused' && +{state}.step === {}", at + 3)).await;
        w.click("#resume-host").await;
        w.until("the run playing again", &format!("{state}.state === 'playing'")).await;

        // A checkpoint of the run (no component is connected any more), to the file named in
        // the field; it appears in the root and among those Restore offers, and is put back.
        w.type_into("#checkpoint-path", "browser").await;
        w.click("#save-checkpoint").await;
        let result = "document.querySelector('#checkpoint-result')";
        w.until(
            "the checkpoint saved",
            &format!("{result}.dataset.result === 'ok' && {result}.dataset.file === 'browser.tutti-checkpoint'"),
        )
        .await;
        w.message_contains("checkpoint saved to browser.tutti-checkpoint").await;
        let file = w.root.join("browser.tutti-checkpoint");
        assert!(file.is_file(), "{} not written", file.display());
        w.until(
            "the checkpoint offered to Restore",
            "document.querySelector(\"#checkpoints option[value='browser.tutti-checkpoint']\")",
        )
        .await;
        w.click("#restore-checkpoint").await;
        w.until(
            "the checkpoint restored",
            &format!("{result}.dataset.result === 'ok' && {result}.textContent.startsWith('restored')"),
        )
        .await;
        // A file that is not a checkpoint: refused, with the run's reason in the page.
        w.type_into("#checkpoint-path", "multiuav.ddf").await;
        w.click("#restore-checkpoint").await;
        w.until("the restore refused", &format!("{result}.dataset.result === 'error'")).await;
        w.message_contains("not a tutti checkpoint").await;

        w.click("#stop-host").await;
        w.message_contains("stopped tutti host").await;
        let ns = w.namespace.as_str();
        let segments = || async move {
            let left = common::segments_of(ns);
            if left.is_empty() {
                Ok(())
            } else {
                Err(left)
            }
        };
        retry(Duration::from_millis(100), |_| true, segments).await.unwrap_or_else(|left| panic!("segments left: {left:?}"));
        w.close().await;
    })
    .await;
}

/// Tries `attempt` until it succeeds: an error that `again` accepts is tried again after
/// `pause` for as long as [`WAIT`] allows, any other (or the last) is returned.
///
/// Written out, not one of `tutti_test_support`'s waits: those block the thread they run
/// on, which the browser's async session needs.
async fn retry<T, E, F: Future<Output = Result<T, E>>>(
    pause: Duration,
    again: impl Fn(&E) -> bool,
    mut attempt: impl FnMut() -> F,
) -> Result<T, E> {
    let deadline = Instant::now() + WAIT;
    loop {
        match attempt().await {
            Ok(v) => return Ok(v),
            Err(e) if again(&e) && Instant::now() < deadline => tokio::time::sleep(pause).await,
            Err(e) => return Err(e),
        }
    }
}

/// Whether a WebDriver error says the element was replaced since it was found.
fn is_stale(e: &fantoccini::error::CmdError) -> bool {
    e.to_string().contains("stale element")
}
