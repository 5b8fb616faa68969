//! A column chunk whose pages are encoded here (`split_pages`' floats, `int_pages`'
//! integers): its pages as the file's page writer writes them, and what its metadata,
//! offset index and row group record of them, as parquet-rs's column writer keeps them.

use bytes::Bytes;
use parquet::basic::{
    Compression, Encoding, EncodingMask, PageType, Type as PhysicalType, ZstdLevel,
};
use parquet::column::page::{CompressedPage, Page};
use parquet::column::writer::ColumnCloseResult;
use parquet::errors::ParquetError;
use parquet::file::metadata::{
    ColumnChunkMetaData, LevelHistogram, OffsetIndexBuilder, PageEncodingStats,
};
use parquet::file::properties::{EnabledStatistics, WriterPropertiesPtr, WriterVersion};
use parquet::file::statistics::Statistics;
use parquet::schema::types::ColumnDescPtr;

use crate::parquet_columns::ChunkPages;

/// The writer settings a column whose pages are encoded here takes from the file's.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PageSettings {
    /// Values encoded between checks of the page's size (in a list, then up to a row's
    /// end).
    pub(crate) batch: usize,
    /// A page is cut once it holds this many rows…
    pub(crate) page_rows: usize,
    /// … or its values' encoded size is this many bytes.
    pub(crate) page_bytes: usize,
    /// The pages' compression.
    pub(crate) zstd: ZstdLevel,
}

impl PageSettings {
    /// The settings of the leaf `descr` in the file's `props`, or `None` unless the leaf
    /// is of `physical` type and they are the tables': version 1 pages, no dictionary,
    /// `encoding` (a column without one of its own is written PLAIN), chunk statistics, no
    /// bloom filter, zstd.
    pub(crate) fn of(
        descr: &ColumnDescPtr,
        props: &WriterPropertiesPtr,
        physical: PhysicalType,
        encoding: Encoding,
    ) -> Option<Self> {
        let path = descr.path();
        let Compression::ZSTD(zstd) = props.compression(path) else {
            return None;
        };
        let taken = descr.physical_type() == physical
            && props.statistics_enabled(path) == EnabledStatistics::Chunk
            && props.writer_version() == WriterVersion::PARQUET_1_0
            && !props.dictionary_enabled(path)
            && props.encoding(path).unwrap_or(Encoding::PLAIN) == encoding
            && props.bloom_filter_properties(path).is_none()
            && props.write_batch_size() > 0;
        taken.then(|| Self {
            batch: props.write_batch_size(),
            page_rows: props.data_page_row_count_limit(),
            page_bytes: props.column_data_page_size_limit(path),
            zstd,
        })
    }
}

/// The pages of one column chunk, all in one encoding, zstd-compressed: of required values
/// (each defined; in lists, each row's first value at repetition level 0), or of a flat
/// nullable column's (its nulls at definition level 0).
pub(crate) struct ChunkLedger {
    descr: ColumnDescPtr,
    encoding: Encoding,
    zstd: ZstdLevel,
    pages: ChunkPages,
    offset_index: Option<OffsetIndexBuilder>,
    page_count: i32,
    rows: u64,
    values: u64,
    /// Values that are null (definition level 0), of `values`.
    nulls: u64,
    uncompressed_bytes: u64,
    compressed_bytes: u64,
    bytes_written: u64,
    first_page_offset: Option<u64>,
}

impl ChunkLedger {
    /// An empty chunk of the leaf `descr`, its pages in `encoding` compressed at `zstd`,
    /// with an offset index unless the file's `props` leave it out.
    pub(crate) fn new(
        descr: ColumnDescPtr,
        props: &WriterPropertiesPtr,
        encoding: Encoding,
        zstd: ZstdLevel,
    ) -> Self {
        Self {
            descr,
            encoding,
            zstd,
            pages: ChunkPages::default(),
            offset_index: (!props.offset_index_disabled()).then(OffsetIndexBuilder::new),
            page_count: 0,
            rows: 0,
            values: 0,
            nulls: 0,
            uncompressed_bytes: 0,
            compressed_bytes: 0,
            bytes_written: 0,
            first_page_offset: None,
        }
    }

    /// The chunk's zstd level.
    pub(crate) fn zstd(&self) -> ZstdLevel {
        self.zstd
    }

    /// Appends a version 1 data page of `values` values (`nulls` of them null) in `rows`
    /// rows, its bytes (levels, then values) compressed in `buf`, `uncompressed` bytes
    /// before.
    pub(crate) fn push(
        &mut self,
        buf: Bytes,
        uncompressed: usize,
        rows: usize,
        values: usize,
        nulls: usize,
    ) -> Result<(), ParquetError> {
        let num_values = u32::try_from(values)
            .map_err(|_| ParquetError::General(format!("a page of {values} values")))?;
        let page = Page::DataPage {
            buf,
            num_values,
            encoding: self.encoding,
            def_level_encoding: Encoding::RLE,
            rep_level_encoding: Encoding::RLE,
            statistics: None,
        };
        let spec = self.pages.push(CompressedPage::new(page, uncompressed))?;
        if let Some(index) = &mut self.offset_index {
            index.append_row_count(rows as i64);
            index.append_unencoded_byte_array_data_bytes(None);
            let size = i32::try_from(spec.compressed_size)
                .map_err(|_| ParquetError::General("a page of more than 2 GiB".into()))?;
            index.append_offset_and_size(spec.offset as i64, size);
        }
        self.page_count += 1;
        self.rows += rows as u64;
        self.values += values as u64;
        self.nulls += nulls as u64;
        self.uncompressed_bytes += spec.uncompressed_size as u64;
        self.compressed_bytes += spec.compressed_size as u64;
        self.bytes_written += spec.bytes_written;
        self.first_page_offset.get_or_insert(spec.offset);
        Ok(())
    }

    /// The chunk's pages and what the row group records of them, its values bounded by
    /// `statistics`.
    pub(crate) fn close(
        self,
        statistics: Statistics,
    ) -> Result<(ChunkPages, ColumnCloseResult), ParquetError> {
        // The levels' encoding is always listed; the values' once a page has it.
        let mut encodings = vec![Encoding::RLE];
        let mut page_stats = Vec::new();
        if self.page_count > 0 {
            encodings.push(self.encoding);
            page_stats.push(PageEncodingStats {
                page_type: PageType::DATA_PAGE,
                encoding: self.encoding,
                count: self.page_count,
            });
        }
        let as_i64 =
            |v: u64| i64::try_from(v).map_err(|_| ParquetError::General("a chunk past i64".into()));
        // The levels' histograms (none for a flat required column): each row's first value
        // at repetition level 0, the others at 1; every value defined but the nulls.
        let mut repetition = LevelHistogram::try_new(self.descr.max_rep_level());
        if let Some(h) = &mut repetition {
            h.increment_by(0, as_i64(self.rows)?);
            h.increment_by(1, as_i64(self.values - self.rows)?);
        }
        let mut definition = LevelHistogram::try_new(self.descr.max_def_level());
        if let Some(h) = &mut definition {
            h.increment_by(0, as_i64(self.nulls)?);
            h.increment_by(
                self.descr.max_def_level(),
                as_i64(self.values - self.nulls)?,
            );
        }
        let metadata = ColumnChunkMetaData::builder(self.descr.clone())
            .set_compression(Compression::ZSTD(self.zstd))
            .set_encodings_mask(EncodingMask::new_from_encodings(encodings.iter()))
            .set_page_encoding_stats(page_stats)
            .set_total_compressed_size(as_i64(self.compressed_bytes)?)
            .set_total_uncompressed_size(as_i64(self.uncompressed_bytes)?)
            .set_num_values(as_i64(self.values)?)
            .set_data_page_offset(as_i64(self.first_page_offset.unwrap_or(0))?)
            .set_dictionary_page_offset(None)
            .set_statistics(statistics)
            .set_unencoded_byte_array_data_bytes(None)
            .set_repetition_level_histogram(repetition)
            .set_definition_level_histogram(definition)
            .build()?;
        let close = ColumnCloseResult {
            bytes_written: self.bytes_written,
            rows_written: self.rows,
            metadata,
            bloom_filter: None,
            column_index: None,
            offset_index: self.offset_index.map(OffsetIndexBuilder::build),
        };
        Ok((self.pages, close))
    }
}
