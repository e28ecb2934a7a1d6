// Reads an MCAP file with Foxglove's @mcap/core (indexed reader, zstd via fzstd) and prints
// one JSON object: every channel with its schema name and encoding, and message counts.
import { readFile } from "node:fs/promises";
import { McapIndexedReader } from "@mcap/core";
import { decompress } from "fzstd";

const path = process.argv[2];
const bytes = await readFile(path);
const readable = {
  size: async () => BigInt(bytes.byteLength),
  read: async (offset, length) => bytes.subarray(Number(offset), Number(offset + length)),
};
const reader = await McapIndexedReader.Initialize({
  readable,
  decompressHandlers: { zstd: (data, size) => decompress(data, new Uint8Array(Number(size))) },
});
const channels = {};
for (const [id, channel] of reader.channelsById) {
  const schema = reader.schemasById.get(channel.schemaId);
  channels[id] = {
    topic: channel.topic,
    messageEncoding: channel.messageEncoding,
    schemaName: schema ? schema.name : null,
    schemaEncoding: schema ? schema.encoding : null,
    count: 0,
  };
}
const decoder = new TextDecoder();
let parsed = 0;
for await (const message of reader.readMessages()) {
  const channel = channels[message.channelId];
  channel.count += 1;
  JSON.parse(decoder.decode(message.data)); // every payload must be valid JSON
  parsed += 1;
}
const metadata = [];
for await (const record of reader.readMetadata()) {
  metadata.push(record.name);
}
console.log(JSON.stringify({ channels: Object.values(channels), parsed, metadata,
  attachments: reader.attachmentIndexes.map((a) => a.name) }));
