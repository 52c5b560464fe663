//! MCAP files of gelgrip's topics, as ROS 2 tools read them: profile `ros2`, one `ros2msg`
//! schema per type (the `.msg` text with its dependencies), one `cdr` channel per topic, and
//! each message logged at its header's stamp (the capture time). Chunks are uncompressed:
//! the JPEG images, most of the bytes, do not compress, and no C compression library is
//! built.

use std::collections::BTreeMap;
use std::io::{Seek, Write};

use thiserror::Error;

use gelgrip_ros_bridge::feed::{Sample, Topic};

/// An MCAP write failed.
#[derive(Debug, Error)]
#[error("writing MCAP: {0}")]
pub struct McapError(#[from] mcap::McapError);

/// A ROS 2 MCAP file being written.
pub struct McapOut<W: Write + Seek> {
    writer: mcap::Writer<W>,
    channels: Vec<u16>,
    sequence: Vec<u32>,
    /// Messages written.
    pub messages: u64,
}

impl<W: Write + Seek> McapOut<W> {
    /// Start a file on `w` with a channel per topic.
    pub fn create(w: W, topics: &[Topic]) -> Result<Self, McapError> {
        let mut writer = mcap::WriteOptions::new()
            .compression(None)
            .profile("ros2")
            .create(w)?;
        let mut schemas: BTreeMap<&str, u16> = BTreeMap::new();
        let mut channels = Vec::with_capacity(topics.len());
        for t in topics {
            let schema = match schemas.get(t.ty.name) {
                Some(&id) => id,
                None => {
                    let id =
                        writer.add_schema(t.ty.name, "ros2msg", t.ty.schema_text().as_bytes())?;
                    schemas.insert(t.ty.name, id);
                    id
                }
            };
            let mut meta = BTreeMap::new();
            meta.insert("topic_type_hash".to_string(), t.ty.rihs01());
            channels.push(writer.add_channel(schema, &t.name, "cdr", &meta)?);
        }
        Ok(Self {
            writer,
            sequence: vec![0; channels.len()],
            channels,
            messages: 0,
        })
    }

    /// Log `sample` at its stamp.
    pub fn write(&mut self, sample: &Sample) -> Result<(), McapError> {
        let (Some(&channel_id), Some(seq)) = (
            self.channels.get(sample.topic),
            self.sequence.get_mut(sample.topic),
        ) else {
            return Ok(());
        };
        *seq = seq.wrapping_add(1);
        let t = sample.stamp.unix_ns();
        self.writer.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id,
                sequence: *seq,
                log_time: t,
                publish_time: t,
            },
            &sample.cdr,
        )?;
        self.messages += 1;
        Ok(())
    }

    /// Write the summary and close the file.
    pub fn finish(mut self) -> Result<u64, McapError> {
        self.writer.finish()?;
        Ok(self.messages)
    }
}
