// A Unix-domain socket listening at a path, with a thread that accepts one client and reads
// everything it sends: a reader for the tests of outputs written to a socket.
#pragma once

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstring>
#include <stdexcept>
#include <string>
#include <thread>

namespace lmalign::test {

class SocketListener {
 public:
  /// Binds and listens at `path` (throws std::runtime_error if it cannot), then accepts one
  /// client on a thread (waiting at most 60 s) and reads until it closes.
  explicit SocketListener(const std::string& path) {
    server_ = ::socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un address{};
    address.sun_family = AF_UNIX;
    std::strncpy(address.sun_path, path.c_str(), sizeof(address.sun_path) - 1);
    if (server_ < 0 ||
        ::bind(server_, reinterpret_cast<sockaddr*>(&address), sizeof(address)) != 0 ||
        ::listen(server_, 1) != 0) {
      if (server_ >= 0) ::close(server_);
      throw std::runtime_error("cannot listen at " + path);
    }
    reader_ = std::thread([this] {
      // A writer that never connects leaves received() empty after 60 s instead of a hang.
      pollfd pending{server_, POLLIN, 0};
      if (::poll(&pending, 1, 60000) != 1) return;
      const int client = ::accept(server_, nullptr, nullptr);
      if (client < 0) return;
      char buffer[4096];
      for (ssize_t n; (n = ::read(client, buffer, sizeof(buffer))) > 0;) {
        received_.append(buffer, static_cast<std::size_t>(n));
      }
      ::close(client);
    });
  }
  SocketListener(const SocketListener&) = delete;
  SocketListener& operator=(const SocketListener&) = delete;
  ~SocketListener() {
    if (reader_.joinable()) reader_.join();
    ::close(server_);
  }

  /// Waits for the client to close; what it sent.
  const std::string& received() {
    if (reader_.joinable()) reader_.join();
    return received_;
  }

 private:
  int server_ = -1;
  std::thread reader_;
  std::string received_;
};

}  // namespace lmalign::test
