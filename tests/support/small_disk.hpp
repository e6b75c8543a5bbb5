// A small filesystem of a test's own (tmpfs of a given size), to see what the code does when the
// disk is full. Needs root (as CI and the bench server have); mounted() says whether it worked.
#pragma once

#include <sys/mount.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace hil::test {
class SmallDisk {
 public:
  SmallDisk(const std::filesystem::path& at, const char* size) : at_(at) {
    std::filesystem::create_directories(at);
    mounted_ = ::mount("tmpfs", at.c_str(), "tmpfs", 0, (std::string("size=") + size).c_str()) == 0;
  }
  ~SmallDisk() {
    if (mounted_) ::umount2(at_.c_str(), MNT_DETACH);
  }
  bool mounted() const { return mounted_; }
  // Fills the disk to the last byte with a file of its own.
  void fill() const {
    std::ofstream out(at_ / "filler", std::ios::binary);
    const std::string block(1 << 16, 'x');
    while (out.write(block.data(), static_cast<std::streamsize>(block.size()))) {}
    out.clear();
    out.close();  // the last partial block
    std::ofstream small(at_ / "filler2", std::ios::binary);
    for (int i = 0; i < 1 << 16 && small.put('x'); ++i) {}
  }
  void unfill() const {
    std::filesystem::remove(at_ / "filler");
    std::filesystem::remove(at_ / "filler2");
  }

 private:
  std::filesystem::path at_;
  bool mounted_ = false;
};

}  // namespace hil::test
