//! Rewriting a log that a crash cut off into a complete MCAP file.
//!
//! A cut file has no summary section and no footer, so readers that seek (the official MCAP
//! readers' `make_reader` on a file, Foxglove's indexed loading) refuse it; only a streaming read
//! gets its data. [`rewrite_complete`] copies every record that survived, in order, into a new
//! file with chunk indexes, statistics and a footer, as `mcap recover` does.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use mcap::read::{LinearReader, Options, RawMessageStream};
use mcap::records::{MessageHeader, Record};
use mcap::Attachment;

use super::LogError;

/// Copy what survives of the cut log `from` into a complete MCAP file at `to`: metadata and
/// attachments, then every whole message with its channel and schema. Returns the number of
/// messages copied. `to` appears only when it is complete (written as `to.part`, then renamed).
pub fn rewrite_complete(from: &Path, to: &Path) -> Result<usize, LogError> {
    let name = from.display().to_string();
    let io = |path: &Path| {
        let path = path.display().to_string();
        move |source| LogError::Io { path, source }
    };
    let bytes = std::fs::read(from).map_err(io(from))?;
    let mut part = to.as_os_str().to_owned();
    part.push(".part");
    let part = std::path::PathBuf::from(part);
    let mcap_error = |source| LogError::Mcap { path: part.display().to_string(), source };
    let file = File::create(&part).map_err(io(&part))?;
    let mut writer = super::writer::write_options(format!("arash {} (recovered)", env!("CARGO_PKG_VERSION")))
        .create(BufWriter::new(file))
        .map_err(mcap_error)?;

    let records = LinearReader::new_with_options(&bytes, Options::IgnoreEndMagic.into())
        .map_err(|source| LogError::NotMcap { path: name.clone(), source })?;
    for record in records {
        match record {
            Ok(Record::Metadata(m)) => writer.write_metadata(&m).map_err(mcap_error)?,
            Ok(Record::Attachment { header, data, .. }) => writer
                .attach(&Attachment {
                    log_time: header.log_time,
                    create_time: header.create_time,
                    name: header.name,
                    media_type: header.media_type,
                    data,
                })
                .map_err(mcap_error)?,
            Ok(_) => {}
            Err(_) => break, // the cut
        }
    }

    let mut stream = RawMessageStream::new_with_options(&bytes, Options::IgnoreEndMagic.into())
        .map_err(|source| LogError::NotMcap { path: name.clone(), source })?;
    let mut channels: BTreeMap<u16, u16> = BTreeMap::new();
    let mut copied = 0;
    while let Some(Ok(message)) = stream.next() {
        let old = message.header.channel_id;
        let id = match channels.get(&old) {
            Some(&id) => id,
            None => {
                let Some(channel) = stream.get_channel(old) else { continue };
                let schema = match &channel.schema {
                    Some(s) => writer.add_schema(&s.name, &s.encoding, &s.data).map_err(mcap_error)?,
                    None => 0,
                };
                let id = writer
                    .add_channel(schema, &channel.topic, &channel.message_encoding, &channel.metadata)
                    .map_err(mcap_error)?;
                channels.insert(old, id);
                id
            }
        };
        let header = MessageHeader { channel_id: id, ..message.header };
        writer.write_to_known_channel(&header, &message.data).map_err(mcap_error)?;
        copied += 1;
    }
    writer.finish().map_err(mcap_error)?;
    drop(writer);
    std::fs::rename(&part, to).map_err(io(to))?;
    Ok(copied)
}
