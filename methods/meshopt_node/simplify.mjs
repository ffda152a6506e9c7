// meshoptimizer calls for the bench suite's meshopt* rows (methods/meshopt.py).
//
// Reads requests from stdin until it ends, answers each on stdout, in order; one Node
// process serves all the calls of a job process.
// Request:  u32 (little-endian) header length, the JSON header, then `header.bytes` bytes:
//   indices    index_count                      x u32
//   positions  vertex_count * 3                 x f32
//   attributes vertex_count * attribute_count   x f32  (when attribute_count > 0)
//   lock       vertex_count                     x u8   (when header.lock is true)
// Header: {op, bytes, index_count, vertex_count, attribute_count, weights, lock,
//          target_index_count, target_error, flags}
//   op: "simplify" | "attributes" | "update" | "sloppy" | "version"
// Reply: u32 header length, the JSON header {bytes, index_count, error, scale, seconds,
// version, node}, then `bytes` bytes: the kept indices (index_count x u32) and, for
// "update", the updated positions and attributes (laid out as in the request).
// A request the script refuses gets the reply header {refused: "one line", bytes: 0}; a
// request cut short by the end of stdin gets that reply too, then the script exits.

import { readFileSync } from 'node:fs';
import { performance } from 'node:perf_hooks';
import { MeshoptSimplifier } from 'meshoptimizer';

const VERSION = JSON.parse(
	readFileSync(new URL('./node_modules/meshoptimizer/package.json', import.meta.url), 'utf8')
).version;

class Refused extends Error {}

function fail(message) {
	throw new Refused(message.replace(/\s+/g, ' ').trim());
}

function slice(buffer, offset, bytes, Type, what) {
	if (offset + bytes > buffer.length) {
		fail(`malformed request: ${what} need ${bytes} bytes, the body has ${Math.max(0, buffer.length - offset)} left`);
	}
	// copy into a fresh, aligned buffer (the library writes back into some of them)
	const copy = new Uint8Array(bytes);
	copy.set(buffer.subarray(offset, offset + bytes));
	return new Type(copy.buffer);
}

function count(header, key) {
	const value = header[key];
	if (!Number.isInteger(value) || value < 0) fail(`header field ${key} must be a whole number >= 0, got ${JSON.stringify(value)}`);
	return value;
}

function parse(header, body) {
	if (header.op === 'version') return { header };
	const indexCount = count(header, 'index_count');
	const vertexCount = count(header, 'vertex_count');
	const attributeCount = header.attribute_count === undefined ? 0 : count(header, 'attribute_count');
	if (indexCount % 3 !== 0) fail(`index buffer of ${indexCount} indices is not whole triangles`);
	let offset = 0;
	const indices = slice(body, offset, indexCount * 4, Uint32Array, 'the indices');
	offset += indexCount * 4;
	const positions = slice(body, offset, vertexCount * 12, Float32Array, 'the positions');
	offset += vertexCount * 12;
	let attributes = null;
	if (attributeCount > 0) {
		attributes = slice(body, offset, vertexCount * attributeCount * 4, Float32Array, 'the attributes');
		offset += vertexCount * attributeCount * 4;
	}
	let lock = null;
	if (header.lock) {
		lock = slice(body, offset, vertexCount, Uint8Array, 'the vertex locks');
		offset += vertexCount;
	}
	if (offset !== body.length) fail(`malformed request: ${body.length - offset} bytes beyond the buffers the header declares`);
	for (let i = 0; i < indexCount; ++i) {
		if (indices[i] >= vertexCount) fail(`index ${indices[i]} at position ${i} is out of range for ${vertexCount} vertices`);
	}
	for (let i = 0; i < positions.length; ++i) {
		if (!Number.isFinite(positions[i])) fail(`position component ${i} is not finite (${positions[i]})`);
	}
	return { header, indices, positions, attributes, attributeCount, lock, vertexCount };
}

function run(request) {
	const { header, indices, positions, attributes, attributeCount, lock } = request;
	const target = count(header, 'target_index_count');
	const error = Number(header.target_error);
	const flags = header.flags || [];
	const weights = header.weights || [];
	if (target > indices.length || target % 3 !== 0) fail(`target_index_count ${target} must be a multiple of 3 and at most ${indices.length}`);
	if (!(error >= 0)) fail(`target_error must be >= 0, got ${header.target_error}`);
	if (['attributes', 'update'].includes(header.op) && weights.length !== attributeCount) {
		fail(`${weights.length} attribute weights for ${attributeCount} attributes`);
	}
	const scale = MeshoptSimplifier.getScale(positions, 3);
	const start = performance.now();
	let kept, resultError;
	switch (header.op) {
		case 'simplify':
			[kept, resultError] = MeshoptSimplifier.simplify(indices, positions, 3, target, error, flags);
			break;
		case 'attributes':
			[kept, resultError] = MeshoptSimplifier.simplifyWithAttributes(
				indices, positions, 3, attributes, attributeCount, weights, lock, target, error, flags);
			break;
		case 'update': {
			const [n, e] = MeshoptSimplifier.simplifyWithUpdate(
				indices, positions, 3, attributes, attributeCount, weights, lock, target, error, flags);
			kept = indices.subarray(0, n);
			resultError = e;
			break;
		}
		case 'sloppy':
			[kept, resultError] = MeshoptSimplifier.simplifySloppy(indices, positions, 3, lock, target, error);
			break;
		default:
			fail(`unknown op ${JSON.stringify(header.op)}`);
	}
	const seconds = (performance.now() - start) / 1000;
	const parts = [new Uint8Array(kept.buffer, kept.byteOffset, kept.byteLength)];
	if (header.op === 'update') {
		parts.push(new Uint8Array(positions.buffer), new Uint8Array(attributes.buffer));
	}
	return [{ index_count: kept.length, error: resultError, scale, seconds }, parts];
}

function answer(reply, parts) {
	const bytes = parts.reduce((n, p) => n + p.byteLength, 0);
	const head = Buffer.from(JSON.stringify({ ...reply, bytes }), 'utf8');
	const length = Buffer.alloc(4);
	length.writeUInt32LE(head.length, 0);
	process.stdout.write(Buffer.concat([length, head, ...parts.map((p) => Buffer.from(p.buffer, p.byteOffset, p.byteLength))]));
}

function serve(header, body) {
	try {
		const request = parse(header, body);
		const about = { version: VERSION, node: process.version };
		if (header.op === 'version') return answer(about, []);
		const [reply, parts] = run(request);
		answer({ ...reply, ...about }, parts);
	} catch (err) {
		const message = err instanceof Refused ? err.message : `meshoptimizer ${VERSION}: ${err.message}`;
		answer({ refused: message }, []);
	}
}

await MeshoptSimplifier.ready;
let pending = Buffer.alloc(0);
process.stdin.on('data', (chunk) => {
	pending = pending.length ? Buffer.concat([pending, chunk]) : chunk;
	for (;;) {
		if (pending.length < 4) return;
		const headerBytes = pending.readUInt32LE(0);
		if (pending.length < 4 + headerBytes) return;
		let header;
		try {
			header = JSON.parse(pending.subarray(4, 4 + headerBytes).toString('utf8'));
		} catch (err) {
			answer({ refused: `request header is not JSON: ${err.message}` }, []);
			process.exit(0); // the stream cannot be resynchronised
		}
		const bytes = Number.isInteger(header.bytes) && header.bytes >= 0 ? header.bytes : 0;
		if (pending.length < 4 + headerBytes + bytes) return;
		const body = pending.subarray(4 + headerBytes, 4 + headerBytes + bytes);
		pending = pending.subarray(4 + headerBytes + bytes);
		serve(header, body);
	}
});
process.stdin.on('end', () => {
	if (pending.length > 0) {
		let what = `${pending.length} bytes`;
		if (pending.length >= 4) {
			const headerBytes = pending.readUInt32LE(0);
			what = pending.length < 4 + headerBytes ? `header of ${headerBytes} bytes, ${pending.length - 4} given`
				: `${pending.length - 4 - headerBytes} bytes of body, fewer than its header declares`;
		}
		answer({ refused: `truncated request: ${what}` }, []);
	}
});
