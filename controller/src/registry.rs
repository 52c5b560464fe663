//! The transport registry: hub transports are chosen by name (`hub.transport` in TOML).
//!
//! Each backend crate provides a [`HubFactory`]; the binary registers the ones it was built
//! with. Names that the contract reserves but this build lacks get a clear error that lists
//! what is available.

use std::sync::Arc;

use crate::clock::Clock;
use crate::config::{BackendSection, ConfigError, FieldCheck};
use crate::hub::{HubError, HubTransport, TriggerMode};
use crate::layout::HandLayout;

/// Opens one kind of hub transport.
pub trait HubFactory: Send + Sync {
    /// The registry name (`sim`, `cdc`, …).
    fn name(&self) -> &'static str;
    /// Check the transport's config section without opening anything.
    fn validate(&self, section: &BackendSection, layout: &HandLayout) -> Result<(), ConfigError>;
    /// Open the transport.
    fn open(&self, request: OpenRequest<'_>) -> Result<Box<dyn HubTransport>, OpenError>;
}

/// Everything a factory needs to open a transport.
#[derive(Debug)]
pub struct OpenRequest<'a> {
    /// The transport's config section.
    pub section: &'a BackendSection,
    /// The hand layout (sensor order = board order).
    pub layout: &'a HandLayout,
    /// Trigger mode.
    pub trigger: TriggerMode,
    /// The injected clock.
    pub clock: Arc<dyn Clock>,
}

/// Why a transport could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    /// Its configuration is invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The device failed.
    #[error(transparent)]
    Hub(#[from] HubError),
}

/// Transport names the contract reserves, with the issue that brings each.
const PLANNED: [(&str, &str); 0] = [];

/// The transports this build can open.
#[derive(Default)]
pub struct TransportRegistry {
    factories: Vec<Box<dyn HubFactory>>,
}

impl std::fmt::Debug for TransportRegistry {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.names()).finish()
    }
}

impl TransportRegistry {
    /// An empty registry.
    pub fn new() -> Self {
        Self::default()
    }

    /// Add a transport.
    pub fn register(&mut self, factory: Box<dyn HubFactory>) {
        self.factories.push(factory);
    }

    /// Registered names.
    pub fn names(&self) -> Vec<&'static str> {
        self.factories.iter().map(|f| f.name()).collect()
    }

    /// The factory named `name`, or an error naming the field and listing what exists.
    fn factory(&self, check: &FieldCheck, name: &str) -> Result<&dyn HubFactory, ConfigError> {
        self.factories
            .iter()
            .find(|f| f.name() == name)
            .map(|f| f.as_ref())
            .ok_or_else(|| {
                let later = PLANNED.iter().find(|(n, _)| *n == name).map(|(_, l)| *l);
                check.unavailable("hub.transport", name, later, &self.names())
            })
    }

    /// Error unless `name` is registered.
    pub fn check_name(&self, check: &FieldCheck, name: &str) -> Result<(), ConfigError> {
        self.factory(check, name).map(|_| ())
    }

    /// Let transport `name` validate its section.
    pub fn validate(
        &self,
        name: &str,
        section: &BackendSection,
        layout: &HandLayout,
    ) -> Result<(), ConfigError> {
        self.factory(&section.check, name)?
            .validate(section, layout)
    }

    /// Open transport `name`.
    pub fn open(
        &self,
        name: &str,
        request: OpenRequest<'_>,
    ) -> Result<Box<dyn HubTransport>, OpenError> {
        self.factory(&request.section.check, name)?.open(request)
    }
}
