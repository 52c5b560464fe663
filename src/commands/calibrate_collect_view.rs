//! Serving the calibration view of `calibrate collect` on a hardware hub
//! ([`gelgrip_web::calibrate`]): bound like `run`'s dashboard (`--http ADDR`, else
//! `[http] bind`; off loopback only with a token, which every route then needs), its URL
//! printed to stderr as `dashboard: http://ADDR/`, and shut down gracefully when the
//! session ends, so that the answer to the last Keep reaches the page.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use tokio::sync::oneshot;
use tokio::task::JoinHandle;

use gelgrip_controller::config::AppConfig;
use gelgrip_web::calibrate::CollectView;
use gelgrip_web::feed::check_bind;

/// Longest wait for the open requests when the session ends.
const DRAIN: Duration = Duration::from_secs(2);

/// The served view.
pub struct ViewServer {
    stop: oneshot::Sender<()>,
    task: JoinHandle<()>,
}

impl ViewServer {
    /// Bind `bind` (checked as the dashboard's) and serve `view`.
    pub async fn start(
        config: &AppConfig,
        bind: SocketAddr,
        view: Arc<CollectView>,
    ) -> anyhow::Result<Self> {
        check_bind(bind, config.http.token.as_deref()).map_err(gelgrip::Error::from)?;
        let token = config
            .http
            .token
            .clone()
            .filter(|t| !t.is_empty() && !bind.ip().is_loopback());
        let listener = tokio::net::TcpListener::bind(bind)
            .await
            .with_context(|| format!("binding the calibration view to {bind}"))?;
        let addr = listener.local_addr()?;
        let app = gelgrip_web::calibrate::app(view, token);
        let (stop, stopped) = oneshot::channel::<()>();
        let task = tokio::spawn(async move {
            let serve = axum::serve(listener, app).with_graceful_shutdown(async {
                let _ = stopped.await;
            });
            if let Err(e) = serve.await {
                tracing::error!("calibration view server: {e}");
            }
        });
        eprintln!("dashboard: http://{addr}/");
        Ok(Self { stop, task })
    }

    /// Stop taking connections and let the open requests finish (at most [`DRAIN`]).
    pub async fn shut_down(self) {
        let _ = self.stop.send(());
        let mut task = self.task;
        if tokio::time::timeout(DRAIN, &mut task).await.is_err() {
            task.abort();
        }
    }
}
