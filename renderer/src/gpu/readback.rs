//! Read-backs ([`GpuContext::read_buffer`], [`GpuContext::stage`], [`GpuContext::read_staged`],
//! [`GpuContext::read_textures`]): copies into staging buffers from the pool, mapped with one
//! wait for the device and copied once to the host.

use super::context::GpuContext;
use super::pool::Contents;
use rayon::prelude::*;
use std::sync::Arc;

/// Bytes of mapped memory one thread copies at a time when a buffer is read back.
const READ_BLOCK: usize = 1 << 18;

impl GpuContext {
    /// Reads a whole buffer (created with `MAP_READ | COPY_DST`) back to the CPU (copied once,
    /// in blocks on all threads).
    pub fn read_buffer(&self, buffer: &wgpu::Buffer) -> Vec<u8> {
        self.mapped(buffer, copy_blocks::<u8>).unwrap_or_default()
    }

    /// Maps a `MAP_READ` buffer (waiting for the device), hands its bytes to `read` and unmaps
    /// it; `None` when it cannot be mapped.
    pub(super) fn mapped<R>(&self, buffer: &wgpu::Buffer, read: impl FnOnce(&[u8]) -> R) -> Option<R> {
        self.map_all(&[buffer]);
        self.take_mapped(buffer, read)
    }

    /// Copies a storage buffer to a staging buffer (from the pool) and reads it back as `f32`s.
    pub fn read_f32(&self, source: &wgpu::Buffer) -> Vec<f32> {
        self.read_staged_f32(&self.stage(source))
    }

    /// Copies a storage buffer to a staging buffer (from the pool) and reads its bytes back.
    pub fn read_storage(&self, source: &wgpu::Buffer) -> Vec<u8> {
        self.read_buffer(&self.stage(source))
    }

    /// Submits the copy of a storage buffer into a staging buffer from the pool (`MAP_READ`) and
    /// returns the staging buffer, without waiting: [`GpuContext::read_staged_f32`] reads it.
    pub fn stage(&self, source: &wgpu::Buffer) -> Arc<wgpu::Buffer> {
        // from the pool: the copy below writes all of it
        let staging = self.buffer("readback", source.size(), wgpu::BufferUsages::MAP_READ, Contents::Overwritten);
        let mut encoder = self.encoder();
        encoder.copy_buffer_to_buffer(source, 0, &staging, 0, source.size());
        self.submit(encoder);
        staging
    }

    /// Submits the copies of `sources`, one after another, into one staging buffer from the pool
    /// (`MAP_READ`), without waiting: [`GpuContext::read_staged`] reads it with the frame's other
    /// read-backs. Each source starts at the sum of the sizes before it.
    pub fn stage_all(&self, sources: &[&wgpu::Buffer]) -> Arc<wgpu::Buffer> {
        let size = sources.iter().map(|s| s.size()).sum::<u64>().max(wgpu::COPY_BUFFER_ALIGNMENT);
        // from the pool: the copies below write every byte read back
        let staging = self.buffer("readback", size, wgpu::BufferUsages::MAP_READ, Contents::Overwritten);
        let mut encoder = self.encoder();
        let mut at = 0;
        for source in sources {
            encoder.copy_buffer_to_buffer(source, 0, &staging, at, source.size());
            at += source.size();
        }
        self.submit(encoder);
        staging
    }

    /// Maps several staging buffers with one wait for the device, and copies each once (in
    /// blocks on all threads) as 32-bit words (`bytemuck::cast_slice` makes them `f32`s or
    /// bytes).
    pub fn read_staged(&self, staging: &[&wgpu::Buffer]) -> Vec<Vec<u32>> {
        self.map_all(staging);
        staging.iter().map(|buffer| self.take_mapped(buffer, copy_blocks::<u32>).unwrap_or_default()).collect()
    }

    /// As [`GpuContext::read_staged`], with the first staging buffer's mapped bytes handed to
    /// `first` instead of copied (a live frame makes its image straight from them); `None`
    /// for it when it cannot be mapped.
    pub fn read_staged_with<R>(
        &self,
        first: &wgpu::Buffer,
        rest: &[&wgpu::Buffer],
        read: impl FnOnce(&[u8]) -> R,
    ) -> (Option<R>, Vec<Vec<u32>>) {
        self.map_all(&[&[first], rest].concat());
        let out = self.take_mapped(first, read);
        (out, rest.iter().map(|buffer| self.take_mapped(buffer, copy_blocks::<u32>).unwrap_or_default()).collect())
    }

    /// Maps staging buffers for reading, with one wait for the device.
    fn map_all(&self, staging: &[&wgpu::Buffer]) {
        // the copies into them submitted first
        self.flush();
        for buffer in staging {
            buffer.slice(..).map_async(wgpu::MapMode::Read, |_| {});
        }
        self.wait();
    }

    /// A mapped buffer's bytes handed to `read`, then unmapped (counted as read back).
    fn take_mapped<R>(&self, buffer: &wgpu::Buffer, read: impl FnOnce(&[u8]) -> R) -> Option<R> {
        self.count_readback(buffer.size());
        let out = buffer.slice(..).get_mapped_range().ok().map(|view| read(&view));
        buffer.unmap();
        out
    }

    /// Maps a staging buffer (waiting for the device) and copies it once, straight into
    /// `f32`s, in blocks on all threads.
    pub fn read_staged_f32(&self, staging: &wgpu::Buffer) -> Vec<f32> {
        self.mapped(staging, copy_blocks::<f32>).unwrap_or_default()
    }

    /// Reads a 2D texture of 16-byte texels (`Rgba32Float`) back as `[f32; 4]` per texel.
    pub fn read_texture_rgba32(&self, texture: &wgpu::Texture) -> Vec<[f32; 4]> {
        self.read_texture(texture, 16).chunks_exact(16).map(|c| *bytemuck::from_bytes::<[f32; 4]>(c)).collect()
    }

    /// Reads a 2D texture (layer 0) with `texel_bytes` per texel, rows unpadded.
    pub fn read_texture(&self, texture: &wgpu::Texture, texel_bytes: u32) -> Vec<u8> {
        self.read_textures(&[(texture, texel_bytes)]).pop().unwrap_or_default()
    }

    /// Reads several 2D textures (layer 0; each with its bytes per texel) in one copy, one
    /// submission and one wait; each texture's bytes with rows unpadded.
    pub fn read_textures(&self, textures: &[(&wgpu::Texture, u32)]) -> Vec<Vec<u8>> {
        let layouts: Vec<(u64, u32, u32, u32)> = textures
            .iter()
            .scan(0u64, |at, &(texture, texel_bytes)| {
                let row = texture.width() * texel_bytes;
                let padded = row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
                let offset = *at;
                *at += padded as u64 * texture.height() as u64;
                Some((offset, row, padded, texture.height()))
            })
            .collect();
        let size = layouts.last().map_or(0, |&(offset, _, padded, h)| offset + padded as u64 * h as u64);
        if size == 0 {
            return vec![Vec::new(); textures.len()];
        }
        // from the pool: the copies below write every byte read back (not rows' padding)
        let staging = self.buffer("texture readback", size, wgpu::BufferUsages::MAP_READ, Contents::Overwritten);
        let mut encoder = self.encoder();
        for (&(texture, _), &(offset, _, padded, h)) in textures.iter().zip(&layouts) {
            encoder.copy_texture_to_buffer(
                texture.as_image_copy(),
                wgpu::TexelCopyBufferInfo {
                    buffer: &staging,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset,
                        bytes_per_row: Some(padded),
                        rows_per_image: Some(h),
                    },
                },
                wgpu::Extent3d { width: texture.width(), height: h, depth_or_array_layers: 1 },
            );
        }
        self.submit(encoder);
        // rows copied straight from the mapped memory without their padding, on all threads
        self.mapped(&staging, |view| {
            layouts
                .iter()
                .map(|&(offset, row, padded, h)| {
                    let mut out = vec![0u8; (row * h) as usize];
                    if row > 0 {
                        out.par_chunks_mut(row as usize).enumerate().for_each(|(y, to)| {
                            let from = offset as usize + y * padded as usize;
                            to.copy_from_slice(&view[from..from + row as usize]);
                        });
                    }
                    out
                })
                .collect()
        })
        .unwrap_or_else(|| vec![Vec::new(); textures.len()])
    }
}

/// `bytes` as `T`s, copied once, in blocks of [`READ_BLOCK`] bytes on all threads: reading
/// mapped memory is slow from one thread (a 1024×768 frame's 38 MB took 10–22 ms on an H200's
/// host).
pub(super) fn copy_blocks<T: bytemuck::Pod>(bytes: &[u8]) -> Vec<T> {
    let mut out = vec![T::zeroed(); bytes.len() / std::mem::size_of::<T>()];
    let whole = std::mem::size_of_val(out.as_slice());
    bytemuck::cast_slice_mut::<T, u8>(&mut out)
        .par_chunks_mut(READ_BLOCK)
        .zip(bytes[..whole].par_chunks(READ_BLOCK))
        .for_each(|(to, from)| to.copy_from_slice(from));
    out
}
