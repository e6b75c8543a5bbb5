// Fuzz target: one text message from a Foxglove WebSocket client (foxglove::parse_client_op).
// It must never throw: every input is a Subscribe, an Unsubscribe or an Error with a message, and
// the status the server answers with must dump as JSON whatever bytes the message quoted.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string_view>
#include <variant>

#include "fuzz_support.hpp"
#include "server/foxglove.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  hil::fuzz::expect_clear_errors<>("foxglove client op", [&] {
    const auto op = hil::bench::foxglove::parse_client_op(text);
    if (const auto* e = std::get_if<hil::bench::foxglove::Error>(&op)) {
      if (e->message.empty()) {
        std::fprintf(stderr, "\nFINDING: an error without a message\n");
        std::abort();
      }
      (void)hil::bench::foxglove::status(2, e->message).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
    }
  });
  return 0;
}
