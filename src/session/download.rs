//! What a vehicle holds, read back whole (`emplan download`): its mission, its geofence and its
//! rally points, each the autopilot's list of its mission type (the fence and the rally points
//! only from an autopilot that declares it holds them in AUTOPILOT_VERSION), and the mission a
//! mission file would give of them, its fence and rally points filled in.

use crate::link::connection::{Autopilot, Link};
use crate::link::driver::{download_of, DriverError};
use crate::link::fence::{fence_of_items, rally_of_items, FenceItemsError, FENCE, RALLY};
use crate::link::mav::{MavMissionType, MISSION_ITEM_INT_DATA};
use crate::link::support::{AskConfig, Capabilities};
use crate::link::transfer::TransferConfig;
use crate::link::LinkError;
use crate::mission::Mission;

/// Why what the vehicle holds could not be read.
#[derive(Debug, thiserror::Error)]
pub enum DownloadError {
    #[error("link: {0}")]
    Link(#[from] LinkError),
    #[error("downloading the {list}: {source}")]
    Transfer {
        list: &'static str,
        source: DriverError,
    },
    #[error("reading the vehicle's {0}")]
    Items(#[from] FenceItemsError),
    #[error("reading the {count} mission items as a mission: {source}")]
    Mission {
        count: usize,
        source: crate::mission::MissionError,
    },
}

/// The lists a vehicle holds, as it answered them.
#[derive(Debug, Clone, PartialEq)]
pub struct Held {
    pub autopilot: Autopilot,
    pub capabilities: Capabilities,
    pub items: Vec<MISSION_ITEM_INT_DATA>,
    /// Empty when the autopilot holds no fence.
    pub fence_items: Vec<MISSION_ITEM_INT_DATA>,
    /// Empty when the autopilot holds no rally points.
    pub rally_items: Vec<MISSION_ITEM_INT_DATA>,
}

async fn list(
    mission_type: MavMissionType,
    link: &Link,
    target: &Autopilot,
    transfer: TransferConfig,
) -> Result<Vec<MISSION_ITEM_INT_DATA>, DownloadError> {
    download_of(mission_type, link, target, transfer)
        .await
        .map_err(|source| DownloadError::Transfer {
            list: crate::link::driver::list_name(mission_type),
            source,
        })
}

/// Reads `target`'s mission, and its fence and rally points when it declares it holds them.
pub async fn download_held(
    link: &Link,
    target: &Autopilot,
    transfer: TransferConfig,
) -> Result<Held, DownloadError> {
    let capabilities =
        crate::link::commands::capabilities(link, target, AskConfig::default()).await?;
    let items = list(crate::link::transfer::MISSION_TYPE, link, target, transfer).await?;
    let fence_items = match capabilities.fence {
        true => list(FENCE, link, target, transfer).await?,
        false => Vec::new(),
    };
    let rally_items = match capabilities.rally {
        true => list(RALLY, link, target, transfer).await?,
        false => Vec::new(),
    };
    Ok(Held {
        autopilot: *target,
        capabilities,
        items,
        fence_items,
        rally_items,
    })
}

impl Held {
    /// The mission the items hold (`link::items::mission_of_items`, named `name`), with the
    /// vehicle's fence and rally points.
    pub fn mission(&self, name: &str) -> Result<Mission, DownloadError> {
        let mut mission =
            crate::link::items::mission_of_items(&self.items, self.autopilot.flavour, name)
                .map_err(|source| DownloadError::Mission {
                    count: self.items.len(),
                    source,
                })?;
        mission.fence = fence_of_items(&self.fence_items)?;
        mission.rally = rally_of_items(&self.rally_items)?;
        Ok(mission)
    }
}
