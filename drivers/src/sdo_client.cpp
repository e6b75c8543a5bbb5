#include "hil/drv/sdo_client.hpp"

#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/post.hpp>

#include <cstdio>
#include <future>

#include "hil/drv/canopen.hpp"
#include "hil/drv/socketcan.hpp"

namespace hil::drv {

namespace asio = boost::asio;
using namespace canopen;
using std::chrono::milliseconds;

namespace {
// CiA 301: "client/server command specifier not valid or unknown", how the client refuses a
// segmented transfer it does not implement.
constexpr std::uint32_t kSdoAbortCommandSpecifier = 0x05040001;
constexpr std::uint32_t kSdoAbortTimedOut = 0x05040000;  // "SDO protocol timed out"
}  // namespace

struct SdoClient::Request {
  bool upload = false;
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::uint32_t value = 0;
  std::uint8_t size = 0;
  int tries = 0;
  // Replies that did not answer this request (another object, the wrong service): a node that
  // answers wrongly is not a silent one, and the timeout message says so.
  int ignored = 0;
  std::string last_ignored;
  std::promise<std::uint32_t> done;
};

SdoClient::SdoClient(asio::io_context& io, Settings settings, DeviceHealth& health, Link link)
    : io_(io), settings_(std::move(settings)), h_(health), link_(std::move(link)), timer_(io) {}

SdoClient::~SdoClient() = default;

void SdoClient::cancel() noexcept { timer_.cancel(); }

void SdoClient::on_reply(const CanFrame& f) {
  const auto r = parse_sdo_reply(f);
  if (r.kind == SdoReply::Kind::malformed) {
    ++h_.malformed;
    link_.error(settings_.who + ": malformed SDO reply " + to_string(f));
    return;
  }
  if (!active_) return;  // stray reply, e.g. late for a request that already timed out
  auto req = active_;
  const auto ignore = [&] {
    ++req->ignored;
    req->last_ignored = to_string(f);
  };
  if (r.index != req->index || r.sub != req->sub) return ignore();
  const std::string obj = object_name(req->index, req->sub);
  const std::string op = req->upload ? "SDO read " + obj : "SDO write " + obj;
  switch (r.kind) {
    case SdoReply::Kind::upload:
      if (!req->upload) return ignore();
      return finish(nullptr, r.value);
    case SdoReply::Kind::download:
      if (req->upload) return ignore();
      return finish(nullptr, 0);
    case SdoReply::Kind::abort: {
      ++h_.aborts_or_exceptions;
      char code[16];
      std::snprintf(code, sizeof code, "0x%08X", r.value);
      const std::string text = settings_.who + ": " + op + ": abort " + code + " (" + std::string(sdo_abort_name(r.value)) + ")";
      link_.error(text);
      return finish(std::make_exception_ptr(SdoAbortError(text, req->index, req->sub, r.value)), 0);
    }
    default: {
      const std::string text =
          settings_.who + ": " + op + ": the drive started a segmented transfer; only expedited SDO is supported";
      link_.error(text);
      // Tell the node, or its SDO server stays in the transfer waiting for our segment requests.
      link_.send(sdo_abort(settings_.node_id, req->index, req->sub, kSdoAbortCommandSpecifier, false));
      return finish(std::make_exception_ptr(DriveError(text)), 0);
    }
  }
}

void SdoClient::finish(std::exception_ptr err, std::uint32_t value) {
  link_.publish();  // counters first: the caller may look at health() as soon as it wakes
  timer_.cancel();
  auto req = std::move(active_);
  active_.reset();
  if (err)
    req->done.set_exception(err);
  else
    req->done.set_value(value);
  next();
}

void SdoClient::next() {
  if (active_ || queue_.empty()) return;
  active_ = queue_.front();
  queue_.pop_front();
  send_active();
}

void SdoClient::send_active() {
  auto& r = *active_;
  ++r.tries;
  const std::uint8_t n = settings_.node_id;
  link_.send(r.upload ? sdo_upload(n, r.index, r.sub) : sdo_download(n, r.index, r.sub, r.value, r.size));
  timer_.expires_after(settings_.timeout);
  timer_.async_wait([this, req = active_](const boost::system::error_code& ec) {
    if (ec || active_ != req) return;
    ++h_.timeouts;
    if (req->tries <= settings_.retries) {
      send_active();
      return;
    }
    const std::string text =
        settings_.who + ": SDO " + (req->upload ? "read " : "write ") + object_name(req->index, req->sub) +
        (req->ignored == 0 ? ": no reply after " : ": no matching reply after ") + std::to_string(req->tries) + " tries of " +
        std::to_string(settings_.timeout.count()) + " ms" +
        (req->ignored == 0 ? std::string()
                           : " (" + std::to_string(req->ignored) +
                                 " replies ignored: another object or the wrong service; last " + req->last_ignored + ")");
    link_.error(text);
    // CiA 301: the client aborts a transfer it gave up on, so a node that was merely slow drops
    // it rather than answering it into the next request.
    link_.send(sdo_abort(settings_.node_id, req->index, req->sub, kSdoAbortTimedOut, false));
    link_.publish();
    finish(std::make_exception_ptr(DriveError(text)), 0);
  });
}

std::uint32_t SdoClient::transfer(bool upload, std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size) {
  if (io_.get_executor().running_in_this_thread()) throw DriveError(settings_.who + ": SDO called from the I/O thread");
  auto req = std::make_shared<Request>();
  req->upload = upload, req->index = index, req->sub = sub, req->value = value, req->size = size;
  auto fut = req->done.get_future();
  asio::post(io_, [this, req] {
    queue_.push_back(req);
    next();
  });
  const auto budget = (settings_.timeout + milliseconds(50)) * (settings_.retries + 1) * 4 + std::chrono::seconds(2);
  // In slices, so that a cancelled setup call does not wait out the request's tries. The request
  // stays with the I/O thread, which ends it by its own timeout.
  const auto until = Clock::now() + budget;
  while (fut.wait_for(milliseconds(2)) != std::future_status::ready) {
    if (link_.check_cancelled) link_.check_cancelled();
    if (Clock::now() > until) {
      throw DriveError(settings_.who + ": SDO " + object_name(index, sub) + ": the I/O thread did not answer");
    }
  }
  return fut.get();
}

std::uint32_t SdoClient::read(std::uint16_t index, std::uint8_t sub) { return transfer(true, index, sub, 0, 0); }

void SdoClient::write(std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size) {
  transfer(false, index, sub, value, size);
}

// ---- a channel of its own ----------------------------------------------------------------------

SdoChannel::SdoChannel(const std::string& interface, SdoClient::Settings settings, CanTransportFactory transport) {
  if (!transport) transport = SocketCanTransport::factory(interface);
  const std::uint32_t n = settings.node_id;
  tr_ = transport(io_, {{kSdoTx + n, 0x7FF}});
  sdo_ = std::make_unique<SdoClient>(io_, std::move(settings), h_,
                                     SdoClient::Link{.send =
                                                         [this](const CanFrame& f) {
                                                           const bool sent = tr_->send(f);
                                                           ++(sent ? h_.tx_frames : h_.tx_failed);
                                                           return sent;
                                                         },
                                                     .error = [this](const std::string& text) { h_.set_last_error(text); },
                                                     .publish = [this] { health_box_.store(h_); },
                                                     .check_cancelled = {}});
  tr_->start([this](const CanFrame& f) {
    if (f.error) return;
    ++h_.rx_frames;
    sdo_->on_reply(f);
    health_box_.store(h_);
  });
  health_box_.store(h_);
  thread_ = std::thread([this] {
    auto work = asio::make_work_guard(io_);
    io_.run();
  });
}

SdoChannel::~SdoChannel() {
  // Stopped from the I/O thread itself, so the channel is closed before run() returns.
  asio::post(io_, [this] {
    tr_->stop();
    sdo_->cancel();
    io_.stop();
  });
  if (thread_.joinable()) thread_.join();
}

}  // namespace hil::drv
