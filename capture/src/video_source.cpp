// SPDX-License-Identifier: MIT
// VideoSource over libavformat (demux) + libavcodec (decode) + libswscale (to RGB24). The decode
// loop is the send_packet/receive_frame state machine: receive until the decoder wants input, then
// feed it the next packet of the chosen stream; at the end of the file the decoder is flushed with a
// null packet so frames held back for reordering still come out. Everything this file allocates
// (contexts, packet, frame, the RGB buffer, the swscale context for the stream's declared pixel
// format) is allocated at configure; acquire only allocates what libav does internally (demuxer
// packet buffers, decoder frame pools) or a new swscale context if a stream changes format mid-way.
#include "gs/capture/video_source.h"

#include <sys/stat.h>

#include <cmath>
#include <cstring>
#include <vector>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/avutil.h>
#include <libavutil/imgutils.h>
#include <libavutil/log.h>
#include <libswscale/swscale.h>
}

namespace gs::capture {
namespace {

std::string av_error_text(int err) {
  char buf[AV_ERROR_MAX_STRING_SIZE] = {0};
  av_strerror(err, buf, sizeof(buf));
  return buf;
}

// libswscale warns about the deprecated full-range "yuvj" formats and wants the range given
// separately; map them to the plain formats and report full range instead.
AVPixelFormat plain_format(AVPixelFormat f, bool* full_range) {
  switch (f) {
    case AV_PIX_FMT_YUVJ420P: *full_range = true; return AV_PIX_FMT_YUV420P;
    case AV_PIX_FMT_YUVJ422P: *full_range = true; return AV_PIX_FMT_YUV422P;
    case AV_PIX_FMT_YUVJ444P: *full_range = true; return AV_PIX_FMT_YUV444P;
    case AV_PIX_FMT_YUVJ440P: *full_range = true; return AV_PIX_FMT_YUV440P;
    case AV_PIX_FMT_YUVJ411P: *full_range = true; return AV_PIX_FMT_YUV411P;
    default: return f;
  }
}

int sws_colorspace(AVColorSpace cs) {
  switch (cs) {
    case AVCOL_SPC_BT709: return SWS_CS_ITU709;
    case AVCOL_SPC_BT2020_NCL:
    case AVCOL_SPC_BT2020_CL: return SWS_CS_BT2020;
    case AVCOL_SPC_SMPTE240M: return SWS_CS_SMPTE240M;
    case AVCOL_SPC_FCC: return SWS_CS_FCC;
    default: return SWS_CS_DEFAULT;  // untagged streams are BT.601, as the ffmpeg CLI assumes
  }
}

}  // namespace

struct VideoSource::Impl {
  AVFormatContext* fmt = nullptr;
  AVCodecContext* dec = nullptr;
  AVPacket* pkt = nullptr;
  AVFrame* frame = nullptr;
  SwsContext* sws = nullptr;
  int stream_index = -1;
  AVRational time_base{1, 1};
  int64_t start_pts = 0;  // subtracted so the first frame of a clip is at about 0 ns

  // The scaler's current input, to know when it must be reconfigured.
  int sws_w = 0, sws_h = 0;
  AVPixelFormat sws_fmt = AV_PIX_FMT_NONE;
  bool sws_full_range = false;
  int sws_cs = -1;

  int32_t out_w = 0, out_h = 0, out_stride = 0;
  std::vector<uint8_t> rgb;  // (out_h + 1) * out_stride bytes, the one buffer frames are delivered in

  VideoInfo info;
  bool started = false;
  bool holding = false;       // a frame is out and not released yet
  bool demux_done = false;    // the null (flush) packet has been sent
  bool ended = false;         // kEndOfStream was returned
  bool failed = false;        // an error was returned; only stop() is allowed
  bool truncated = false;
  int read_error = 0;         // a non-EOF error from av_read_frame, kept for messages
  bool last_pkt_corrupt = false;    // the stream's newest packet was flagged corrupt by the demuxer
  bool last_frame_corrupt = false;  // the newest frame came out with concealed decode errors
  uint64_t delivered = 0;
  int64_t last_ts_ns = -1, frame_interval_ns = 0;

  ~Impl() {
    sws_freeContext(sws);
    av_frame_free(&frame);
    av_packet_free(&pkt);
    avcodec_free_context(&dec);
    avformat_close_input(&fmt);
  }
};

VideoSource::VideoSource(std::string path) : path_(std::move(path)), name_("video:" + path_) {}
VideoSource::~VideoSource() = default;

Status VideoSource::configure(const FrameFormat& requested, FrameFormat* actual) {
  impl_.reset();
  const std::string where = "video " + path_;
  struct stat st {};
  if (::stat(path_.c_str(), &st) != 0) return io_error(where + ": no such file");
  if (S_ISDIR(st.st_mode)) return invalid_argument(where + ": is a directory, not a video file");
  if ((requested.width == 0) != (requested.height == 0))
    return invalid_argument(where + ": give both width and height, or neither (native size)");
  if (requested.width < 0 || requested.height < 0)
    return invalid_argument(where + ": negative size requested");

  // libav logs every demuxer and decoder complaint to stderr at INFO; our Status carries the
  // reason, so keep only errors unless the application chose a level itself.
  if (av_log_get_level() == AV_LOG_INFO) av_log_set_level(AV_LOG_ERROR);

  auto m = std::make_unique<Impl>();
  int r = avformat_open_input(&m->fmt, path_.c_str(), nullptr, nullptr);
  if (r < 0) return parse_error(where + ": not a readable video container (" + av_error_text(r) + ")");
  r = avformat_find_stream_info(m->fmt, nullptr);
  if (r < 0) return parse_error(where + ": cannot read stream information (" + av_error_text(r) + ")");

  const AVCodec* codec = nullptr;
  r = av_find_best_stream(m->fmt, AVMEDIA_TYPE_VIDEO, -1, -1, &codec, 0);
  if (r == AVERROR_STREAM_NOT_FOUND) return parse_error(where + ": no video stream in the file");
  if (r == AVERROR_DECODER_NOT_FOUND) {
    // Name the codec the container declares so the user knows what is missing.
    std::string cname = "unknown";
    for (unsigned i = 0; i < m->fmt->nb_streams; ++i)
      if (m->fmt->streams[i]->codecpar->codec_type == AVMEDIA_TYPE_VIDEO) {
        cname = avcodec_get_name(m->fmt->streams[i]->codecpar->codec_id);
        break;
      }
    return unsupported(where + ": no decoder for the video codec '" + cname + "' in this FFmpeg build");
  }
  if (r < 0) return parse_error(where + ": cannot select a video stream (" + av_error_text(r) + ")");
  m->stream_index = r;
  AVStream* st_v = m->fmt->streams[r];
  const AVCodecParameters* par = st_v->codecpar;
  if (par->width <= 0 || par->height <= 0)
    return parse_error(where + ": the video stream has no picture size (corrupt or truncated header)");

  m->dec = avcodec_alloc_context3(codec);
  if (!m->dec) return io_error(where + ": out of memory for the decoder");
  r = avcodec_parameters_to_context(m->dec, par);
  if (r < 0) return parse_error(where + ": bad codec parameters (" + av_error_text(r) + ")");
  m->dec->pkt_timebase = st_v->time_base;
  r = avcodec_open2(m->dec, codec, nullptr);
  if (r < 0) return unsupported(where + ": cannot open the " + codec->name + " decoder (" + av_error_text(r) + ")");

  // Stream description for probe().
  m->time_base = st_v->time_base;
  m->start_pts = st_v->start_time != AV_NOPTS_VALUE ? st_v->start_time : 0;
  AVRational rate = st_v->avg_frame_rate;
  if (rate.num <= 0 || rate.den <= 0) rate = st_v->r_frame_rate;
  VideoInfo& info = m->info;
  info.width = par->width;
  info.height = par->height;
  info.fps = (rate.num > 0 && rate.den > 0) ? av_q2d(rate) : 0.0;
  if (st_v->duration != AV_NOPTS_VALUE && st_v->duration > 0)
    info.duration_s = double(st_v->duration) * av_q2d(st_v->time_base);
  else if (m->fmt->duration != AV_NOPTS_VALUE && m->fmt->duration > 0)
    info.duration_s = double(m->fmt->duration) / AV_TIME_BASE;
  info.frame_count = st_v->nb_frames > 0 ? st_v->nb_frames : int64_t(std::llround(info.duration_s * info.fps));
  info.codec = codec->name;
  m->frame_interval_ns = info.fps > 0 ? int64_t(1e9 / info.fps) : 0;

  // Output size: native, or a downscale.
  if (requested.width == 0) {
    m->out_w = par->width;
    m->out_h = par->height;
  } else {
    if (requested.width > par->width || requested.height > par->height)
      return invalid_argument(where + ": requested " + std::to_string(requested.width) + "x" +
                              std::to_string(requested.height) + " is larger than the video's " +
                              std::to_string(par->width) + "x" + std::to_string(par->height) +
                              " (only downscaling is offered)");
    m->out_w = requested.width;
    m->out_h = requested.height;
  }
  m->out_stride = (m->out_w * 3 + 31) & ~31;  // swscale writes whole aligned SIMD blocks per row
  // swscale's SIMD writers overrun the last row by up to a vector (seen with valgrind at 162x122),
  // so the buffer carries one spare row past what the frame view exposes.
  m->rgb.assign(size_t(m->out_stride) * size_t(m->out_h + 1), 0);

  m->pkt = av_packet_alloc();
  m->frame = av_frame_alloc();
  if (!m->pkt || !m->frame) return io_error(where + ": out of memory for packet/frame");

  impl_ = std::move(m);
  // Build the scaler for the declared pixel format now, so the common case allocates nothing later.
  if (par->format != AV_PIX_FMT_NONE) {
    bool full = par->color_range == AVCOL_RANGE_JPEG;
    const AVPixelFormat f = plain_format(AVPixelFormat(par->format), &full);
    impl_->sws = sws_getCachedContext(nullptr, par->width, par->height, f, impl_->out_w, impl_->out_h,
                                      AV_PIX_FMT_RGB24, SWS_BICUBIC, nullptr, nullptr, nullptr);
    if (impl_->sws) {
      impl_->sws_w = par->width, impl_->sws_h = par->height, impl_->sws_fmt = f;
      impl_->sws_full_range = full, impl_->sws_cs = sws_colorspace(par->color_space);
      sws_setColorspaceDetails(impl_->sws, sws_getCoefficients(impl_->sws_cs), full ? 1 : 0,
                               sws_getCoefficients(SWS_CS_DEFAULT), 1, 0, 1 << 16, 1 << 16);
    }
  }

  if (actual) {
    actual->width = impl_->out_w;
    actual->height = impl_->out_h;
    actual->format = PixelFormat::kRGB24;
    actual->fps = info.fps;
  }
  return Status::Ok();
}

Status VideoSource::start() {
  if (!impl_) return invalid_argument(name_ + ": start before a successful configure");
  impl_->started = true;
  return Status::Ok();
}

Expected<AcquireResult> VideoSource::acquire(int32_t /*timeout_ms*/, FrameView* out) {
  if (!impl_ || !impl_->started) return invalid_argument(name_ + ": acquire before start");
  Impl& m = *impl_;
  const std::string where = "video " + path_;
  if (m.failed) return invalid_argument(where + ": acquire after an error (only stop is allowed)");
  if (m.holding) return invalid_argument(where + ": acquire while a frame is still held (release it first)");
  if (m.ended) return AcquireResult::kEndOfStream;

  for (;;) {
    int r = avcodec_receive_frame(m.dec, m.frame);
    if (r == 0) {
      // Corrupt-flagged frames still come out (the decoder concealed the damage); remember it so
      // an early end of file right after them counts as truncation.
      m.last_frame_corrupt = (m.frame->flags & AV_FRAME_FLAG_CORRUPT) || m.frame->decode_error_flags != 0;
      bool full = m.frame->color_range == AVCOL_RANGE_JPEG;
      const AVPixelFormat f = plain_format(AVPixelFormat(m.frame->format), &full);
      const int cs = sws_colorspace(m.frame->colorspace);
      if (!m.sws || m.sws_w != m.frame->width || m.sws_h != m.frame->height || m.sws_fmt != f ||
          m.sws_full_range != full || m.sws_cs != cs) {
        // Only when the decoder's output differs from what the container declared.
        m.sws = sws_getCachedContext(m.sws, m.frame->width, m.frame->height, f, m.out_w, m.out_h, AV_PIX_FMT_RGB24,
                                     SWS_BICUBIC, nullptr, nullptr, nullptr);
        if (!m.sws) {
          m.failed = true;
          av_frame_unref(m.frame);
          return unsupported(where + ": cannot convert pixel format " +
                             std::string(av_get_pix_fmt_name(f) ? av_get_pix_fmt_name(f) : "?") + " to RGB24");
        }
        sws_setColorspaceDetails(m.sws, sws_getCoefficients(cs), full ? 1 : 0, sws_getCoefficients(SWS_CS_DEFAULT), 1, 0,
                                 1 << 16, 1 << 16);
        m.sws_w = m.frame->width, m.sws_h = m.frame->height, m.sws_fmt = f, m.sws_full_range = full, m.sws_cs = cs;
      }
      uint8_t* dst[4] = {m.rgb.data(), nullptr, nullptr, nullptr};
      int dst_stride[4] = {m.out_stride, 0, 0, 0};
      sws_scale(m.sws, m.frame->data, m.frame->linesize, 0, m.frame->height, dst, dst_stride);

      // Timestamp: best-effort PTS relative to the stream start; without one, one frame interval
      // after the previous frame, so timestamps always increase.
      const int64_t pts = m.frame->best_effort_timestamp;
      int64_t ts = -1;
      if (pts != AV_NOPTS_VALUE) ts = av_rescale_q(pts - m.start_pts, m.time_base, AVRational{1, 1000000000});
      if (ts < 0 || ts <= m.last_ts_ns) ts = m.last_ts_ns < 0 ? 0 : m.last_ts_ns + (m.frame_interval_ns > 0 ? m.frame_interval_ns : 1);
      m.last_ts_ns = ts;
      av_frame_unref(m.frame);

      FrameView v;
      v.width = m.out_w;
      v.height = m.out_h;
      v.format = PixelFormat::kRGB24;
      v.num_planes = 1;
      v.planes[0].data = m.rgb.data();
      v.planes[0].size = size_t(m.out_stride) * size_t(m.out_h);
      v.planes[0].stride = m.out_stride;
      v.timestamp_ns = ts;
      v.sequence = m.delivered++;
      v.buffer_index = 0;
      *out = v;
      m.holding = true;
      return AcquireResult::kFrame;
    }
    if (r == AVERROR_EOF) {
      m.ended = true;
      if (m.delivered == 0) {
        m.failed = true;
        return parse_error(where + ": no frame could be decoded (empty or truncated stream" +
                           (m.read_error ? ", read error: " + av_error_text(m.read_error) : std::string()) + ")");
      }
      // The stream ended early if the demuxer failed, the last data was damaged, or the header
      // promised clearly more than was delivered (only trusted when the duration came from the
      // header, not estimated from the truncated file itself).
      if (m.read_error != 0 || m.last_pkt_corrupt || m.last_frame_corrupt) m.truncated = true;
      if (m.fmt->duration_estimation_method == AVFMT_DURATION_FROM_STREAM && m.info.duration_s > 0 &&
          m.frame_interval_ns > 0) {
        const double delivered_end_s = double(m.last_ts_ns + m.frame_interval_ns) * 1e-9;
        if (delivered_end_s + 1.5 * double(m.frame_interval_ns) * 1e-9 < m.info.duration_s) m.truncated = true;
      }
      return AcquireResult::kEndOfStream;
    }
    if (r != AVERROR(EAGAIN)) {
      if (m.demux_done && m.delivered > 0) {
        // Draining after the end of the file: what failed is the cut-off tail, not the stream.
        m.ended = true;
        m.truncated = true;
        return AcquireResult::kEndOfStream;
      }
      m.failed = true;
      return parse_error(where + ": decode error at frame " + std::to_string(m.delivered) + ": " + av_error_text(r));
    }

    // The decoder wants input.
    if (m.demux_done) {  // cannot happen after a flush, but never spin
      m.failed = true;
      return parse_error(where + ": decoder asked for input after the end of the stream");
    }
    r = av_read_frame(m.fmt, m.pkt);
    if (r < 0) {
      if (r != AVERROR_EOF) m.read_error = r;
      m.demux_done = true;
      avcodec_send_packet(m.dec, nullptr);  // flush: reordered frames come out next
      continue;
    }
    if (m.pkt->stream_index != m.stream_index) {
      av_packet_unref(m.pkt);
      continue;
    }
    m.last_pkt_corrupt = (m.pkt->flags & AV_PKT_FLAG_CORRUPT) != 0;
    r = avcodec_send_packet(m.dec, m.pkt);
    av_packet_unref(m.pkt);
    if (r < 0 && r != AVERROR(EAGAIN)) {
      // A packet the decoder rejects. If it was the last one in the file it is the cut-off tail of
      // a truncated stream: peek whether anything follows before calling it an error.
      const int decode_err = r;
      int next = av_read_frame(m.fmt, m.pkt);
      while (next >= 0 && m.pkt->stream_index != m.stream_index) {
        av_packet_unref(m.pkt);
        next = av_read_frame(m.fmt, m.pkt);
      }
      if (next < 0 && m.delivered > 0) {
        if (next != AVERROR_EOF) m.read_error = next;
        m.demux_done = true;
        m.truncated = true;
        avcodec_send_packet(m.dec, nullptr);
        continue;
      }
      if (next >= 0) av_packet_unref(m.pkt);
      m.failed = true;
      return parse_error(where + ": decode error at frame " + std::to_string(m.delivered) + ": " +
                         av_error_text(decode_err));
    }
  }
}

Status VideoSource::release(const FrameView& frame) {
  if (!impl_) return invalid_argument(name_ + ": release before configure");
  if (!impl_->holding) return invalid_argument(name_ + ": release without an acquired frame");
  if (frame.planes[0].data != impl_->rgb.data() || frame.buffer_index != 0)
    return invalid_argument(name_ + ": release of a frame this source did not hand out");
  impl_->holding = false;  // the buffer is simply overwritten by the next acquire
  return Status::Ok();
}

Status VideoSource::stop() {
  if (impl_) {
    impl_->started = false;
    impl_->holding = false;
  }
  return Status::Ok();
}

VideoInfo VideoSource::probe() const { return impl_ ? impl_->info : VideoInfo{}; }
bool VideoSource::truncated() const { return impl_ && impl_->truncated; }
uint64_t VideoSource::frames_decoded() const { return impl_ ? impl_->delivered : 0; }

}  // namespace gs::capture
