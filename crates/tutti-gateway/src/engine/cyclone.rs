//! Placeholder until the Cyclone engine lands.
use super::*;

#[derive(Debug)]
pub struct Cyclone;

impl Cyclone {
    pub fn open(_cfg: &EngineConfig) -> Result<Cyclone, GatewayError> {
        Err(GatewayError::Invalid("the Cyclone engine is not built".into()))
    }
}

impl Engine for Cyclone {
    fn kind(&self) -> EngineKind {
        EngineKind::Cyclone
    }
    fn domain_id(&self) -> u16 {
        0
    }
    fn own_prefix(&self) -> [u8; PREFIX_LEN] {
        [0; PREFIX_LEN]
    }
    fn writer(&self, _: &str, _: &str, _: &Qos) -> Result<Box<dyn Writer>, GatewayError> {
        unreachable!()
    }
    fn reader(&self, _: &str, _: &str, _: &Qos, _: Decode, _: Sink) -> Result<(), GatewayError> {
        unreachable!()
    }
    fn remote(&self) -> Remote {
        Remote::default()
    }
    fn announce(&self) -> Result<(), GatewayError> {
        Ok(())
    }
}
