// SPDX-License-Identifier: Apache-2.0
// The map-file check on messages the schema does not have yet: a message
// type built at run time (imported erg.v1.MapFile in a repeated field, a
// oneof, a map and a nested repeated self-reference) shows that the check
// finds a MapFile wherever a future schema puts one, and names it.
#include <google/protobuf/descriptor.h>
#include <google/protobuf/descriptor.pb.h>
#include <google/protobuf/dynamic_message.h>
#include <grpcpp/support/status.h>
#include <gtest/gtest.h>

#include "auth/request_checks.h"
#include "erg/v1/job.pb.h"
#include "scheduler/job_manager.h"

namespace gp = google::protobuf;
using erg::server::map_fields_set;

namespace {

// message Future { repeated erg.v1.MapFile maps = 1; oneof o { erg.v1.MapFile one = 2;
//   int32 other = 3; } map<string, erg.v1.MapFile> named = 4; repeated Future nested = 5; }
const gp::Descriptor* future_type(gp::DescriptorPool& pool) {
  gp::FileDescriptorProto file;
  file.set_name("future.proto");
  file.set_package("test");
  file.add_dependency("erg/v1/job.proto");
  file.set_syntax("proto3");
  auto* m = file.add_message_type();
  m->set_name("Future");
  auto field = [&](const char* name, int n, gp::FieldDescriptorProto::Label label,
                   const char* type) {
    auto* f = m->add_field();
    f->set_name(name);
    f->set_number(n);
    f->set_label(label);
    f->set_type(gp::FieldDescriptorProto::TYPE_MESSAGE);
    f->set_type_name(type);
    return f;
  };
  field("maps", 1, gp::FieldDescriptorProto::LABEL_REPEATED, ".erg.v1.MapFile");
  m->add_oneof_decl()->set_name("o");
  field("one", 2, gp::FieldDescriptorProto::LABEL_OPTIONAL, ".erg.v1.MapFile")->set_oneof_index(0);
  auto* other = m->add_field();
  other->set_name("other");
  other->set_number(3);
  other->set_label(gp::FieldDescriptorProto::LABEL_OPTIONAL);
  other->set_type(gp::FieldDescriptorProto::TYPE_INT32);
  other->set_oneof_index(0);
  auto* entry = m->add_nested_type();
  entry->set_name("NamedEntry");
  entry->mutable_options()->set_map_entry(true);
  auto* k = entry->add_field();
  k->set_name("key");
  k->set_number(1);
  k->set_label(gp::FieldDescriptorProto::LABEL_OPTIONAL);
  k->set_type(gp::FieldDescriptorProto::TYPE_STRING);
  auto* v = entry->add_field();
  v->set_name("value");
  v->set_number(2);
  v->set_label(gp::FieldDescriptorProto::LABEL_OPTIONAL);
  v->set_type(gp::FieldDescriptorProto::TYPE_MESSAGE);
  v->set_type_name(".erg.v1.MapFile");
  field("named", 4, gp::FieldDescriptorProto::LABEL_REPEATED, ".test.Future.NamedEntry");
  field("nested", 5, gp::FieldDescriptorProto::LABEL_REPEATED, ".test.Future");
  const gp::FileDescriptor* fd = pool.BuildFile(file);
  return fd ? fd->FindMessageTypeByName("Future") : nullptr;
}

}  // namespace

TEST(RequestChecks, FindsMapFilesInRepeatedOneofMapAndNestedFields) {
  (void)erg::v1::MapFile::descriptor();  // the generated type the pool falls back to
  gp::DescriptorPool pool(gp::DescriptorPool::generated_pool());
  const gp::Descriptor* type = future_type(pool);
  ASSERT_NE(type, nullptr);
  gp::DynamicMessageFactory factory(&pool);
  factory.SetDelegateToGeneratedFactory(true);
  std::unique_ptr<gp::Message> msg(factory.GetPrototype(type)->New());
  const auto* r = msg->GetReflection();
  EXPECT_TRUE(map_fields_set(*msg).empty());

  r->AddMessage(msg.get(), type->FindFieldByName("maps"));
  r->AddMessage(msg.get(), type->FindFieldByName("maps"));
  r->MutableMessage(msg.get(), type->FindFieldByName("one"));
  gp::Message* entry = r->AddMessage(msg.get(), type->FindFieldByName("named"));
  entry->GetReflection()->SetString(entry, entry->GetDescriptor()->FindFieldByName("key"), "k");
  entry->GetReflection()->MutableMessage(entry, entry->GetDescriptor()->FindFieldByName("value"));
  gp::Message* nested = r->AddMessage(msg.get(), type->FindFieldByName("nested"));
  nested = nested->GetReflection()->AddMessage(nested, type->FindFieldByName("nested"));
  nested->GetReflection()->MutableMessage(nested, type->FindFieldByName("one"));

  const auto found = map_fields_set(*msg, "x");
  const std::vector<std::string> want = {"x.maps[0]", "x.maps[1]", "x.one", "x.named[0].value",
                                         "x.nested[0].nested[0].one"};
  EXPECT_EQ(found, want);

  // The refusal names each, and nothing else.
  try {
    erg::server::refuse_map_files(*msg);
    FAIL() << "not refused";
  } catch (const erg::server::ApiError& e) {
    EXPECT_EQ(e.code, grpc::StatusCode::PERMISSION_DENIED);
    for (const char* w : {"maps[0]: ", "one: ", "named[0].value: ", "nested[0].nested[0].one: "})
      EXPECT_NE(std::string(e.what()).find(w), std::string::npos) << w;
  }
}

TEST(RequestChecks, TheObstacleMapOfAJobSpec) {
  erg::v1::JobSpec spec;
  spec.mutable_layers()->mutable_obstacles()->mutable_map()->set_path("/etc/passwd");
  spec.add_events()->mutable_add_obstacle()->set_height_m(2);  // no map in it
  EXPECT_EQ(map_fields_set(spec), std::vector<std::string>{"layers.obstacles.map"});
}

TEST(RequestChecks, EchoedIdsAreBoundedAndPrintable) {
  EXPECT_EQ(erg::server::echo_id("j-0123"), "'j-0123'");
  EXPECT_EQ(erg::server::echo_id("a\x1b[0m\n"), "'a?[0m?'");
  const std::string e = erg::server::echo_id(std::string(100000, 'b'));
  EXPECT_LT(e.size(), 100u);
  EXPECT_NE(e.find("(100000 bytes)"), std::string::npos);
  EXPECT_THROW(erg::server::check_job_id(std::string(65, 'j')), erg::server::ApiError);
  EXPECT_NO_THROW(erg::server::check_job_id("j-0123456789abcdef"));
  EXPECT_NO_THROW(erg::server::check_job_id("../../etc"));  // printable: the store finds nothing
}
